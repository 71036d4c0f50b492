#pragma once
// The immutable, sensor-derived part of a frame: features, per-keypoint depth, grid, BoW.
// Built once by the tracker and shared (read-only) by the Frame and, if it becomes one, the KeyFrame.
#include <memory>
#include <vector>

#include <opencv2/core.hpp>

#include "bow/bow_vector.h"
#include "core/ids.h"
#include "features/feature_grid.h"
#include "features/orb_extractor.h"
#include "geometry/camera.h"

namespace cslam {

class Vocabulary;

// Scale pyramid facts shared by every frame of one extractor.
struct ScalePyramid {
  int num_levels = 8;
  double scale_factor = 1.2, log_scale_factor = 0.0;
  std::vector<double> scale, sigma2, inv_sigma2;
  static std::shared_ptr<const ScalePyramid> from(const OrbExtractor& extractor);
  // Predicted pyramid level of a point at `distance` given its max distance (ORB-SLAM2 style).
  int predict_level(double distance, double max_distance) const;
};

// RGB-D specifics: a virtual stereo baseline turns depth into a right-image coordinate.
struct RgbdParams {
  double bf = 40.0;        // fx * virtual baseline (ORB-SLAM2 uses 40 for TUM)
  double th_depth = 40.0;  // close/far split in baselines: close if depth < th_depth * bf / fx
  double min_depth = 0.1, max_depth = 8.0;  // depth outside is treated as missing
  // Depth at a keypoint is used only if every pixel within this radius has depth and they span
  // at most depth_edge_ratio of it (occlusion boundaries, colour/depth misregistration); 0: off.
  int depth_edge_radius = 4;
  double depth_edge_ratio = 0.1;
  double close_depth(double fx) const { return th_depth * bf / fx; }
};

struct FrameData {
  FrameId id;
  double timestamp = 0;
  PinholeCamera camera;
  RgbdParams rgbd;
  std::shared_ptr<const ScalePyramid> pyramid;
  OrbFeatures features;
  std::vector<float> depth;    // metric depth per keypoint, -1 if missing
  std::vector<float> u_right;  // virtual right coordinate u - bf/depth, -1 if missing
  std::vector<cv::Vec3b> colors;
  FeatureGrid grid;
  std::array<double, 4> bounds{};  // undistorted image bounds
  BowVector bow;
  FeatureVector feature_vector;

  std::size_t size() const { return features.size(); }
  bool has_depth(int i) const { return depth[i] > 0; }
  bool is_close(int i) const { return depth[i] > 0 && depth[i] < rgbd.close_depth(camera.fx); }
  // Back-projects keypoint i with its depth into the camera frame (undistorted coordinates).
  Eigen::Vector3d unproject(int i) const {
    const auto& p = features.undistorted[i];
    return camera.unproject(p.x(), p.y(), depth[i]);
  }
  bool in_bounds(double u, double v) const { return u >= bounds[0] && u < bounds[1] && v >= bounds[2] && v < bounds[3]; }
};

// Builds FrameData from a BGR + raw depth image pair. Depth is looked up at the (distorted)
// keypoint position, as the depth image is registered to the colour image.
std::shared_ptr<const FrameData> make_frame_data(FrameId id, double timestamp, const cv::Mat& bgr, const cv::Mat& depth_raw,
                                                 const PinholeCamera& camera, const RgbdParams& rgbd,
                                                 const OrbExtractor& extractor,
                                                 const std::shared_ptr<const ScalePyramid>& pyramid,
                                                 const Vocabulary& vocabulary, int bow_levels_up = 4);

}  // namespace cslam
