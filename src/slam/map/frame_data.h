#pragma once
// The immutable, sensor-derived part of a frame: features, per-keypoint depth, grid, BoW.
// Built once by the tracker and shared (read-only) by the Frame and, if it becomes one, the KeyFrame.
#include <memory>
#include <optional>
#include <vector>

#include <opencv2/core.hpp>

#include "slam/bow/bow_vector.h"
#include "core/ids.h"
#include "slam/features/feature_grid.h"
#include "slam/features/orb_extractor.h"
#include "geometry/camera.h"
#include "geometry/se3.h"

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
  double bf = 40.0;                         // fx * virtual baseline (ORB-SLAM2 uses 40 for TUM)
  double th_depth = 40.0;                   // close/far split in baselines: close if depth < th_depth * bf / fx
  double min_depth = 0.1, max_depth = 8.0;  // depth outside is treated as missing
  // Depth at a keypoint is used only if every pixel within this radius has depth and they span
  // at most depth_edge_ratio of it (occlusion boundaries, colour/depth misregistration); 0: off.
  int depth_edge_radius = 4;
  double depth_edge_ratio = 0.1;
  // Colour and depth images of one frame may be captured at different instants (the Kinect v1
  // streams of the TUM sequences: 12-16 ms apart on most frames). With the camera's predicted
  // motion over that gap, a keypoint's depth is read where its 3D point lay in the depth image,
  // not at the keypoint's own pixel (make_frame_data's T_depthcam_cam). Off by default: on fr1/desk
  // and fr1/rpy it did not lower the trajectory error (docs/slam.md); cslam-slam --depth-time.
  bool depth_time_compensation = false;
  double close_depth(double fx) const { return th_depth * bf / fx; }
};

// Bag-of-words vectors a frame does not have yet: they are computed when first needed (with_bow).
// Most frames never become keyframes, are never relocalised and are never matched against a
// reference keyframe, so their words would never be read.
struct PendingBow {
  std::shared_ptr<const Vocabulary> vocabulary;  // null: nothing pending
  int levels_up = 4;
};

struct FrameData {
  FrameId id;
  double timestamp = 0;
  PinholeCamera camera;
  RgbdParams rgbd;
  std::shared_ptr<const ScalePyramid> pyramid;
  OrbFeatures features;
  // False for a frame without its full depth image (a robot that saves bandwidth sends it only
  // every few frames: colour only, or depth at a fraction of the pixels, between): the frame is
  // tracked but never becomes a keyframe.
  bool keyframe_depth = true;
  std::vector<float> depth;    // metric depth per keypoint, -1 if missing
  std::vector<float> u_right;  // virtual right coordinate u - bf/depth, -1 if missing
  std::vector<cv::Vec3b> colors;
  FeatureGrid grid;
  std::array<double, 4> bounds{};  // undistorted image bounds
  BowVector bow;                   // empty while `pending_bow` holds a vocabulary (see with_bow)
  FeatureVector feature_vector;
  PendingBow pending_bow;

  std::size_t size() const { return features.size(); }
  bool has_depth(int i) const { return depth[i] > 0; }
  bool is_close(int i) const { return depth[i] > 0 && depth[i] < rgbd.close_depth(camera.fx); }
  // Back-projects keypoint i with its depth into the camera frame (undistorted coordinates).
  Eigen::Vector3d unproject(int i) const {
    const auto& p = features.undistorted[i];
    return camera.unproject(p.x(), p.y(), depth[i]);
  }
  bool in_bounds(double u, double v) const {
    return u >= bounds[0] && u < bounds[1] && v >= bounds[2] && v < bounds[3];
  }
};

// Builds FrameData from a BGR + raw depth image pair. The depth image is registered to the colour
// camera. Without `T_depthcam_cam`, depth is looked up at the (distorted) keypoint position. With
// it (the colour camera's pose at the colour image's instant, seen from the camera at the depth
// image's instant), each keypoint's depth is read where the point along its ray lies in the depth
// image and expressed in the colour camera (depth_at_keypoint). The bag-of-words vectors are left
// pending (PendingBow) with a non-empty `vocabulary`; with_bow computes them. With `T_lastrow_cam`
// (the camera's motion over half of camera.readout_time, from the middle row's instant to the last
// row's), the keypoints are compensated for the rolling shutter (map/rolling_shutter.h) after their
// depth is read. `gray`: the caller's grey image of `bgr`, if it has one (else converted here).
std::shared_ptr<const FrameData> make_frame_data(
    FrameId id, double timestamp, const cv::Mat& bgr, const cv::Mat& depth_raw, const PinholeCamera& camera,
    const RgbdParams& rgbd, const OrbExtractor& extractor, const std::shared_ptr<const ScalePyramid>& pyramid,
    const std::shared_ptr<const Vocabulary>& vocabulary, int bow_levels_up = 4,
    const std::optional<SE3>& T_depthcam_cam = std::nullopt, const std::optional<SE3>& T_lastrow_cam = std::nullopt,
    bool keyframe_depth = true, const cv::Mat& gray = cv::Mat());

// `data` with its bag-of-words vectors: `data` itself if none are pending, else a copy with them
// computed (the copy costs far less than the transform it stands for).
std::shared_ptr<const FrameData> with_bow(std::shared_ptr<const FrameData> data);

// Metric depth, in the colour camera, of the point seen at undistorted pixel `undistorted` (the
// keypoint at distorted pixel `distorted`); 0 if missing, out of range or at an occlusion boundary.
// T_depthcam_cam as above (nullopt: the depth image was taken at the colour image's instant).
double depth_at_keypoint(const cv::Mat& depth_raw, const Eigen::Vector2d& distorted, const Eigen::Vector2d& undistorted,
                         const PinholeCamera& camera, const RgbdParams& rgbd, const std::optional<SE3>& T_depthcam_cam);

}  // namespace cslam
