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
#include "frame/rgbd_frame.h"

namespace cslam {

// What became of one submitted frame, reported by its client's worker once it is consumed.
enum class FrameFate { kNotInitialized, kTracked, kLost, kSkipped, kRejected };
const char* to_string(FrameFate f);

struct FrameDone {
  ClientId client = 0;
  std::uint64_t seq = 0;
  double timestamp = 0;
  FrameFate fate = FrameFate::kRejected;
  bool has_pose = false;     // only for kTracked: never a stale pose
  SE3 T_world_cam;           // camera-to-world in the frame of `group` (the tracked map's frame)
  int group = -1;            // fused group of the map the frame was tracked in
  int map = 0;               // index of the client's map the frame was tracked in
  std::uint64_t map_epoch = 0;       // bumps when a fusion, group BA or loop correction may move maps
  std::uint64_t frames_skipped = 0;  // live frames of this client skipped so far
  double server_ms = 0;              // submit() to done, milliseconds
  // A light frame on which tracking needed full depth: the robot's next frame should carry it.
  bool wants_depth = false;
};

struct SystemConfig {
  // Frames queued per client before submit() blocks the producer.
  std::size_t client_queue_capacity = 8;
  // A client's worker that skipped a live frame, or has one waiting, counts as behind for this long,
  // and one that skipped again while behind as overloaded (WorkerLoad: flow frames under
  // FlowMode::kUnderLoad, longer runs of them while overloaded).
  double behind_hold_s = 1.0;
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
  std::function<void(const ClientInfo& client, const KeyFrameId& keyframe, const RgbdFrame& frame, const SE3& T_cam_depthcam)>
      on_keyframe;
};

}  // namespace cslam
