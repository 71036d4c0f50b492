#pragma once
// What the server tells a robot about one of its frames once the frame's worker consumed it
// (processed, skipped or rejected): the Ack's content before proto/ encodes it.
#include <cstdint>

#include "core/ids.h"
#include "frame/frame_fate.h"
#include "geometry/se3.h"

namespace cslam {

struct FrameDone {
  ClientId client = 0;
  std::uint64_t seq = 0;
  double timestamp = 0;
  FrameFate fate = FrameFate::kRejected;
  bool has_pose = false;             // only for kTracked: never a stale pose
  SE3 T_world_cam;                   // camera-to-world in the frame of `group` (the tracked map's frame)
  GroupId group;                     // fused group of the map the frame was tracked in
  int map = 0;                       // index of the client's map the frame was tracked in
  std::uint64_t map_epoch = 0;       // bumps when a fusion, group BA or loop correction may move maps
  std::uint64_t frames_skipped = 0;  // live frames of this client skipped so far
  double server_ms = 0;              // submit() to done, milliseconds
  // A light frame on which tracking needed full depth: the robot's next frame should carry it.
  bool wants_depth = false;
  // Frames after this one at which tracking expects its next keyframe (TrackResult::keyframe_due_in;
  // 0: no hint): a lean robot spends its byte budget on the full frame due then.
  int keyframe_due_in = 0;
};

}  // namespace cslam
