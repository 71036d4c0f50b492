#pragma once
// Which full frames a robot's byte budget (codec/byte_budget.h) is for. Only full frames become
// keyframes, but not every full frame does: on the demo scenes about half of a lean stream's
// periodic full frames do (a keyframe every 10 frames, a full frame every 5), so a budget spread
// over every full frame spends about half its room on frames the map never keeps. Tracking knows
// when its next keyframe falls due (the periodic keyframe rule), and every ack of a tracked frame
// says it (Ack::keyframe_due_in: that many frames after the acked one; 0: no hint, e.g. a skipped
// or lost frame, and the latest hint stands). The sender spends the budget on a full frame only if
//  - it answers a request for depth (a keyframe waits for it), or
//  - it is at or after the frame the latest hint names, or
//  - no ack has carried a hint yet (a server that sends none, or before tracking is under way:
//    every full frame may spend).
// A full frame that met the hint has used it: hints from acks of frames sent before it are
// stale (they still name it) and are ignored, as depth requests are. The ratio rule can make a
// keyframe sooner than the hint says; such a full frame gets the stream's own codec.
#include <cstdint>

namespace cslam {

class KeyframeHint {
 public:
  // An ack, in the order they come: frame `seq` said the next keyframe falls due `due_in`
  // frames after it (0: no hint).
  void on_ack(std::uint64_t seq, int due_in) {
    if (due_in <= 0 || seq < met_at_) return;  // no hint, or sent before the full frame that met one
    heard_ = true;
    due_seq_ = seq + std::uint64_t(due_in);
  }
  // Whether full frame `seq` may spend the budget (`requested`: it answers a depth request).
  bool expects_keyframe(std::uint64_t seq, bool requested) const {
    return requested || !heard_ || (due_seq_ > 0 && seq >= due_seq_);
  }
  // Full frame `seq` is sent; if it was expected to become a keyframe, the hint is used up.
  // Returns expects_keyframe(seq, requested) as it was: whether the frame may spend the budget.
  bool on_full_frame(std::uint64_t seq, bool requested) {
    if (!expects_keyframe(seq, requested)) return false;
    met_at_ = seq;
    if (heard_) due_seq_ = 0;
    return true;
  }

 private:
  bool heard_ = false;         // an ack carried a hint
  std::uint64_t due_seq_ = 0;  // the frame the latest hint names; 0: used up
  std::uint64_t met_at_ = 0;   // the last full frame that met a hint
};

}  // namespace cslam
