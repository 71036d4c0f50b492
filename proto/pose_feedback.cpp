#include "proto/pose_feedback.h"

#include <algorithm>
#include <limits>

namespace cslam::wire {

Pose to_wire_pose(const SE3& T) {
  Pose p;
  const auto& t = T.translation();
  const auto& q = T.rotation();
  p.set_tx(t.x());
  p.set_ty(t.y());
  p.set_tz(t.z());
  p.set_qx(q.x());
  p.set_qy(q.y());
  p.set_qz(q.z());
  p.set_qw(q.w());
  return p;
}

SE3 from_wire_pose(const Pose& p) {
  Eigen::Quaterniond q(p.qw(), p.qx(), p.qy(), p.qz());
  if (!(q.squaredNorm() > 0) || !std::isfinite(q.squaredNorm())) q = Eigen::Quaterniond::Identity();
  return SE3(q, Eigen::Vector3d(p.tx(), p.ty(), p.tz()));
}

TrackState to_wire(FrameFate fate) {
  switch (fate) {
    case FrameFate::kNotInitialized:
      return TRACK_NOT_INITIALIZED;
    case FrameFate::kTracked:
      return TRACK_OK;
    case FrameFate::kLost:
      return TRACK_LOST;
    case FrameFate::kSkipped:
      return TRACK_SKIPPED;
    case FrameFate::kRejected:
      return TRACK_REJECTED;
  }
  return TRACK_UNSPECIFIED;
}

FrameFate fate_from_wire(TrackState state) {
  switch (state) {
    case TRACK_NOT_INITIALIZED:
      return FrameFate::kNotInitialized;
    case TRACK_OK:
      return FrameFate::kTracked;
    case TRACK_LOST:
      return FrameFate::kLost;
    case TRACK_SKIPPED:
      return FrameFate::kSkipped;
    default:
      return FrameFate::kRejected;
  }
}

void to_wire_ack(const FrameDone& done, std::uint32_t credits, Ack* out) {
  out->set_client_id(done.client);
  out->set_seq(done.seq);
  out->set_credits(credits);
  out->set_state(to_wire(done.fate));
  if (done.fate == FrameFate::kTracked && done.has_pose) *out->mutable_t_world_cam() = to_wire_pose(done.T_world_cam);
  out->set_group(done.group.value());
  out->set_map(std::uint32_t(std::max(0, done.map)));
  out->set_map_epoch(done.map_epoch);
  out->set_timestamp(done.timestamp);
  out->set_frames_skipped(done.frames_skipped);
  out->set_server_ms(done.server_ms);
  out->set_want_depth(done.wants_depth);
  out->set_keyframe_due_in(std::uint32_t(std::max(0, done.keyframe_due_in)));
}

PoseFeedback from_wire_ack(const Ack& ack) {
  PoseFeedback f;
  f.seq = ack.seq();
  f.timestamp = ack.timestamp();
  f.fate = fate_from_wire(ack.state());
  // A pose only counts with a tracked state: a lost frame never shows a (stale) pose.
  f.has_pose = f.fate == FrameFate::kTracked && ack.has_t_world_cam();
  if (f.has_pose) f.T_world_cam = from_wire_pose(ack.t_world_cam());
  if (f.fate == FrameFate::kTracked && !f.has_pose) f.fate = FrameFate::kLost;
  f.group = GroupId::from_value(ack.group());
  f.map = int(ack.map());
  f.map_epoch = ack.map_epoch();
  f.frames_skipped = ack.frames_skipped();
  f.server_ms = ack.server_ms();
  f.want_depth = ack.want_depth();
  const std::uint32_t due_in = ack.keyframe_due_in();
  f.keyframe_due_in = due_in <= std::uint32_t(std::numeric_limits<int>::max()) ? int(due_in) : 0;
  return f;
}

}  // namespace cslam::wire
