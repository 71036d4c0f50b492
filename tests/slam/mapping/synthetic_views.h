#pragma once
// Synthetic keyframe views for the local-mapping tests: random points in front of the camera, each
// with its own random descriptor, seen by views whose keypoints are the exact projections.
#include <functional>
#include <memory>
#include <random>
#include <vector>

#include "geometry/camera.h"
#include "slam/map/frame_data.h"

namespace cslam {

struct Scene {
  std::vector<Eigen::Vector3d> points;  // world
  std::vector<Descriptor> descriptors;  // one per point
};

inline Scene make_scene(int n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> xy(-1.0, 1.0), z(1.5, 4.0);
  std::uniform_int_distribution<std::uint64_t> bits;
  Scene s;
  for (int i = 0; i < n; ++i) {
    s.points.emplace_back(xy(rng), 0.7 * xy(rng), z(rng));
    s.descriptors.push_back(Descriptor{bits(rng), bits(rng), bits(rng), bits(rng)});
  }
  return s;
}

// A view of the scene: keypoint k sees point order[k]; `with_depth(k)` decides if it has depth.
// Every keypoint sits under one vocabulary node, so matching relies on descriptors and geometry;
// the grid serves searches by projection.
inline std::shared_ptr<const FrameData> make_view(const Scene& s, const SE3& T_cam_world, const std::vector<int>& order,
                                                  const std::function<bool(int)>& with_depth,
                                                  const std::shared_ptr<const ScalePyramid>& pyramid) {
  auto f = std::make_shared<FrameData>();
  f->camera = camera_preset("synthetic");
  f->pyramid = pyramid;
  std::vector<int> node;
  for (int k = 0; k < int(order.size()); ++k) {
    const Eigen::Vector3d pc = T_cam_world * s.points[order[k]];
    const Eigen::Vector2d uv = f->camera.project(pc);
    cv::KeyPoint kp(float(uv.x()), float(uv.y()), 31.f, 45.f, 0.f, 0);
    f->features.keypoints.push_back(kp);
    f->features.undistorted.push_back(uv);
    f->features.descriptors.push_back(s.descriptors[order[k]]);
    const bool d = with_depth(k);
    f->depth.push_back(d ? float(pc.z()) : -1.f);
    f->u_right.push_back(d ? float(uv.x() - f->rgbd.bf / pc.z()) : -1.f);
    f->colors.emplace_back(0, 0, 0);
    node.push_back(k);
  }
  f->feature_vector[0] = node;
  f->bounds = f->camera.undistorted_bounds();
  f->grid = FeatureGrid(f->features, f->bounds);
  return f;
}

inline std::vector<int> identity_order(int n) {
  std::vector<int> o(n);
  for (int i = 0; i < n; ++i) o[i] = i;
  return o;
}

}  // namespace cslam
