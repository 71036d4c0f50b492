#pragma once
// When a lean stream's frame is full (full depth and standalone colour) rather than light: when
// the server asked for one (a keyframe is due: the ack's want_depth), and otherwise `depth_every`
// frames after the last full frame. A requested full frame restarts the count, so the periodic
// ones do not follow a fixed grid. The robot's sender (client/frame_sender.cpp) and the offline
// simulation of its stream (cslam-slam --depth-every, tools/slam/lean_sim.h) both use this one
// rule.
namespace cslam {

class FullFrameClock {
 public:
  // Whether the next frame is full. `depth_every` may change between calls (adaptive rate).
  bool next(bool requested, int depth_every) {
    const bool full = requested || ++since_full_ >= depth_every;
    if (full) since_full_ = 0;
    return full;
  }

 private:
  int since_full_ = 0;  // frames since the last full one (the first frame is requested)
};

}  // namespace cslam
