#pragma once
// Dense reconstruction from trajectories: poses (possibly unordered, merged from several
// clients) are matched to RGB-D pairs by timestamp, then fed to a DenseReconstructor.
// Used by cslam-recon and by the server at the end of a run (fused trajectories of a group).
#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "dense/reconstructor.h"
#include "geometry/camera.h"
#include "io/trajectory_io.h"

namespace cslam {

struct DenseProgress {
  int done = 0, total = 0;  // frames processed / to process (after association)
  int used = 0;
};
using DenseProgressCallback = std::function<void(const DenseProgress&)>;

// One TUM-layout dataset folder with the poses (in the common world frame) of its frames.
struct DatasetPoses {
  std::string dataset_dir;
  Trajectory poses;  // any order; several clients' lists may be concatenated
  PinholeCamera camera;
};

// Associates each source's poses one-to-one with its RGB-D pairs (nearest RGB timestamp within
// config.max_time_gap, greedily by smallest gap); unmatched poses count as no_image. Depth
// images are placed at their own time (DenseConfig::depth_time_compensation). With
// threads >= 2 images are decoded on a loader thread. Throws InputError on a missing dataset.
DenseResult reconstruct_from_trajectories(const std::vector<DatasetPoses>& sources, const DenseConfig& config,
                                          const DenseProgressCallback& progress = {});

// In-memory frames (e.g. the frames a server received from one client).
struct TimedRgbd {
  double timestamp = 0;          // the colour image's
  double depth_time_offset = 0;  // the depth image's time minus the colour image's (s)
  cv::Mat bgr, depth;            // CV_8UC3, CV_16UC1
};
struct FramePoses {
  const std::vector<TimedRgbd>* frames = nullptr;
  Trajectory poses;
  PinholeCamera camera;
};
DenseResult reconstruct_from_frames(const std::vector<FramePoses>& sources, const DenseConfig& config,
                                    const DenseProgressCallback& progress = {});

// Matches poses (any order) to sorted frame timestamps; returns (pose, frame index) in frame
// order and the number of poses left without a frame.
struct PoseFrameMatch {
  std::vector<std::pair<StampedPose, int>> matches;
  int unmatched_poses = 0;
};
PoseFrameMatch match_poses_to_frames(Trajectory poses, const std::vector<double>& frame_times, double max_dt);

}  // namespace cslam
