#pragma once
// Frame data for map-structure tests: keypoints 0..n-1 on a grid, all with depth (1 m), distinct
// descriptors, identity geometry. Geometry is irrelevant where it is used.
#include <memory>

#include "slam/map/frame_data.h"

namespace cslam::test {

inline std::shared_ptr<const FrameData> fake_frame_data(int n, const std::shared_ptr<const ScalePyramid>& pyramid) {
  auto f = std::make_shared<FrameData>();
  f->pyramid = pyramid;
  f->camera = camera_preset("synthetic");
  for (int i = 0; i < n; ++i) {
    cv::KeyPoint kp(float(10 + i % 600), float(10 + i / 600), 31.f, 0.f, 0.f, 0);
    f->features.keypoints.push_back(kp);
    f->features.undistorted.emplace_back(kp.pt.x, kp.pt.y);
    f->features.descriptors.push_back(Descriptor{std::uint64_t(i), 0, 0, 0});
    f->depth.push_back(1.0f);
    f->u_right.push_back(kp.pt.x - 40.f);
    f->colors.emplace_back(0, 0, 0);
  }
  return f;
}

}  // namespace cslam::test
