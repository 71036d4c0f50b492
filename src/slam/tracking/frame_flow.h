#pragma once
// Frame-to-frame tracking by optical flow. In a smooth stretch most of a frame's cost is the full
// ORB extraction and the local-map search, although the camera barely moved since the previous
// frame. A flow frame skips both: the previous frame's matched keypoints are carried into the new
// image by pyramidal Lucas-Kanade (seeded where the motion model predicts them), keep their map
// points, and the pose is optimised against those (Tracker::track_flow). The full path runs
// whenever the tracked set thins, a keyframe is due, the run of flow frames is long, or tracking
// is not healthy (Tracker::flow_seeds decides; docs/slam.md "Flow frames").
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "slam/map/frame_data.h"

namespace cslam {

// When a client's frames may be flow frames: never, only while its worker falls behind live
// frames (ClientPipeline: a cheap pose instead of a skipped frame), or always.
enum class FlowMode { kOff, kUnderLoad, kAlways };
const char* to_string(FlowMode m);
FlowMode parse_flow_mode(const std::string& s);  // "off", "under-load", "always"; throws ConfigError

// How far a client's worker is behind its live frames (ClientPipeline decides): keeping up; behind
// (it skipped a frame or has one waiting: FlowMode::kUnderLoad allows flow frames); overloaded (it
// skipped frames again while already behind, so flow frames of FlowConfig::max_run were not enough:
// runs of up to max_run_overloaded, since a flow frame's pose beats a skipped frame's none).
enum class WorkerLoad { kKeepingUp, kBehind, kOverloaded };

struct FlowConfig {
  FlowMode mode = FlowMode::kUnderLoad;
  int window = 9;         // Lucas-Kanade window side (pixels)
  int levels = 2;         // pyramid levels above the image (each halves it)
  int iterations = 10;    // Lucas-Kanade iterations per level at most
  double epsilon = 0.03;  // ... or until the step is below this (pixels)
  // A track is dropped if its window in the new image differs from the old one by more than this
  // mean absolute grey level (0..255): the photometric check (occlusion, blur, a dark frame).
  double max_patch_error = 30;
  int max_run = 3;             // flow frames in a row at most; then a full frame
  int max_run_overloaded = 8;  // ... while the worker is overloaded (WorkerLoad; >= max_run)
  int max_seeds = 200;         // keypoints followed per frame at most (map points first, thinned evenly)
  int min_inliers = 50;        // a flow frame's map-point inliers at least
  // The keyframe rule's estimate on flow frames is scaled by this quantile of the last
  // calibration_window measured actual / estimated ratios, once there are calibration_min of them
  // (Tracker::keyframe_may_be_due).
  double calibration_quantile = 0.1;
  int calibration_window = 20;
  int calibration_min = 5;
  void validate() const;  // throws ConfigError
};

// A grey image's Lucas-Kanade pyramid (cv::buildOpticalFlowPyramid), kept from one frame to the next.
struct FlowPyramid {
  std::vector<cv::Mat> levels;
  bool empty() const { return levels.empty(); }
};
FlowPyramid build_flow_pyramid(const cv::Mat& gray, const FlowConfig& config);

// Where the previous frame's matched keypoints are to be looked for (Tracker::flow_seeds).
struct FlowSeeds {
  std::vector<int> index;              // keypoint in the previous frame
  std::vector<cv::Point2f> predicted;  // distorted pixel the motion model predicts in the new image
  SE3 T_cam_world;                     // the predicted pose
};

// A flow frame: FrameData whose keypoints are the seeds found again (octave, angle and descriptor
// carried from the previous frame's keypoint, position from the flow, depth and colour read in the
// new images), and for each keypoint its seed's index in the previous frame.
struct FlowFrame {
  std::shared_ptr<const FrameData> data;
  std::vector<int> previous_index;
};

// Follows `seeds` from `previous` (its FrameData and pyramid) into the new images. Keypoints whose
// flow fails, leaves the image or fails the forward-backward check are dropped. The BoW vectors
// are left pending (as make_frame_data does).
FlowFrame make_flow_frame(FrameId id, double timestamp, const cv::Mat& bgr, const cv::Mat& depth_raw,
                          const FrameData& previous, const FlowPyramid& previous_pyramid, const FlowPyramid& pyramid,
                          const FlowSeeds& seeds, const FlowConfig& config,
                          const std::shared_ptr<const Vocabulary>& vocabulary, int bow_levels_up,
                          const std::optional<SE3>& T_depthcam_cam, const std::optional<SE3>& T_lastrow_cam,
                          bool keyframe_depth);

}  // namespace cslam
