#pragma once
// What a lean stream (cslam-client --depth-every K) makes of one client's frames, offline: every
// K-th frame, and the first frame `request_delay` frames after tracking asked for full depth
// (the acks in flight), keeps its full depth; the others become light frames with the depth the
// server expands from every S-th pixel of every S-th row (S = light_depth; 0 or 1: none). Colour
// is not degraded (the light frames' H.264 colour is not modelled). Stepped (--sync) runs answer
// a request exactly `request_delay` frames late; threaded multi-client runs queue frames ahead of
// the workers, so there requests are answered later.
#include <mutex>

#include "frame/rgbd_frame.h"

namespace cslam {

struct LeanStreamConfig {
  int depth_every = 1;  // 1: every frame full
  int request_delay = 3;
  int light_depth = 4;
};

class LeanStreamSim {
 public:
  // ConfigError on depth_every < 1, request_delay < 0 or light_depth outside 0..kMaxDepthSubsample.
  explicit LeanStreamSim(LeanStreamConfig config);
  // Frame n of the client (0-based): made light unless it is due to carry full depth.
  void apply(RgbdFrame& frame, int n);
  // Tracking of frame n asked for full depth (FrameDone::wants_depth). Thread-safe with apply().
  void requested(int n);
  int light_frames() const;

 private:
  const LeanStreamConfig config_;
  mutable std::mutex mutex_;
  int requested_at_ = -1;
  int light_frames_ = 0;
};

}  // namespace cslam
