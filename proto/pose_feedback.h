#pragma once
// Pose feedback on the wire: the server turns a worker's FrameDone into the frame's Ack; the
// client turns an Ack back into a PoseFeedback. Part of the protobuf adapter (proto/).
#include "cslam.pb.h"
#include "geometry/se3.h"
#include "frame/frame_done.h"

namespace cslam::wire {

Pose to_wire_pose(const SE3& T);
// Normalises the quaternion; an all-zero quaternion gives the identity rotation.
SE3 from_wire_pose(const Pose& pose);

TrackState to_wire(FrameFate fate);
FrameFate fate_from_wire(TrackState state);

// The Ack for a consumed frame, handing `credits` back. The pose is set only for a tracked frame.
void to_wire_ack(const FrameDone& done, std::uint32_t credits, Ack* out);

// What a client learns from one Ack.
struct PoseFeedback {
  std::uint64_t seq = 0;
  double timestamp = 0;
  FrameFate fate = FrameFate::kRejected;
  bool has_pose = false;  // only for kTracked
  SE3 T_world_cam;        // camera-to-world in the frame of `group`
  GroupId group;
  int map = 0;
  std::uint64_t map_epoch = 0, frames_skipped = 0;
  double server_ms = 0;     // receipt to pose on the server
  bool want_depth = false;  // the server asks for depth (and standalone colour) with the next frame
  int keyframe_due_in = 0;  // frames after this one at which tracking expects its next keyframe; 0: no hint
  double latency_ms = 0;    // client side: frame captured (offered) to ack received
};
PoseFeedback from_wire_ack(const Ack& ack);

}  // namespace cslam::wire
