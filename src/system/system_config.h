#pragma once
// Configuration of the collaborative system as plain structs with defaults.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>

#include "core/ids.h"
#include "geometry/se3.h"
#include "fusion/fusion_manager.h"
#include "slam/slam_config.h"
#include "frame/frame_done.h"
#include "frame/rgbd_frame.h"

namespace cslam {

struct SystemConfig {
  // Frames queued per client before submit() blocks the producer.
  std::size_t client_queue_capacity = 8;
  // A client's worker that skipped a live frame, or has one waiting, counts as behind for this long,
  // and one that skipped again while behind as overloaded (WorkerLoad: flow frames under
  // FlowMode::kUnderLoad, longer runs of them while overloaded).
  double behind_hold_s = 1.0;
  // Client workers tracking at a time, served in arrival order (0: no limit). Fewer than the
  // robots on a machine with fewer cores: frames are tracked in turn at full speed.
  int tracking_slots = 0;
  // Vocabulary file for BoW (empty: the project's default vocabulary).
  std::string vocabulary_path;
  // Map fusion across clients (rate, thresholds).
  FusionConfig fusion;
  // Run the SLAM stages (false: only count frames and record timestamps, for network tests).
  bool run_slam = true;
  // No worker threads: submit() processes the frame on the caller's thread before it returns
  // (deterministic offline runs, cslam-slam --sync; combine with slam.threaded and
  // fusion.threaded off).
  bool stepped = false;
  // Per-client SLAM settings (every client gets the same).
  SlamConfig slam;
  // Called from a client's worker thread after each frame has been consumed (processed, skipped
  // or rejected), e.g. so the network layer can hand the client a credit and its pose back.
  // Must be cheap and must not call back into the system.
  std::function<void(const FrameDone& done)> on_frame_done;
  // Called from a client's worker thread when a frame became a keyframe (a new map's first
  // keyframe too), with that frame and where its depth image was taken (ProcessResult::T_cam_depthcam):
  // the dense map keeps its images. Must be cheap (queue and
  // return) and must not call back into the system.
  std::function<void(const ClientInfo& client, const KeyFrameId& keyframe, const RgbdFrame& frame,
                     const SE3& T_cam_depthcam)>
      on_keyframe;
};

}  // namespace cslam
