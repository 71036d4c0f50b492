#pragma once
// What a lean stream (cslam-client --depth-every K) makes of one client's frames, offline: every
// K-th frame, and the first frame `request_delay` frames after tracking asked for full depth
// (the acks in flight), keeps its full depth; the others become light frames with the depth the
// server expands from every S-th pixel of every S-th row (S = light_depth; 0 or 1: none). With
// coded_colour the colour goes through the client's codecs and back as the server decodes it:
// full frames JPEG at jpeg_quality, light frames one H.264 stream per client
// (video::light_colour_stream(), only the light frames in it, as the client sends them); without
// it the colour is the dataset's, undegraded. Stepped (--sync) runs answer
// a request exactly `request_delay` frames late; threaded multi-client runs queue frames ahead of
// the workers, so there requests are answered later.
#include <memory>
#include <mutex>

#include "codec/video_codec.h"
#include "frame/rgbd_frame.h"

namespace cslam {

struct LeanStreamConfig {
  int depth_every = 1;  // 1: every frame full
  int request_delay = 3;
  int light_depth = 4;
  bool coded_colour = false;
  int jpeg_quality = CodecOptions().jpeg_quality;  // full frames' colour with coded_colour
};

class LeanStreamSim {
 public:
  // ConfigError on depth_every < 1, request_delay < 0, light_depth outside 0..kMaxDepthSubsample
  // or a JPEG quality outside 1..100.
  explicit LeanStreamSim(LeanStreamConfig config);
  // Frame n of the client (0-based): made light unless it is due to carry full depth.
  // With coded_colour, the codecs' errors pass through (InputError from a decoder).
  void apply(RgbdFrame& frame, int n);
  // Tracking of frame n asked for full depth (FrameDone::wants_depth). Thread-safe with apply().
  void requested(int n);
  int light_frames() const;

 private:
  void code_colour(RgbdFrame& frame, bool full);

  const LeanStreamConfig config_;
  CodecOptions full_colour_;  // the full frames' JPEG, checked once in the constructor
  std::unique_ptr<video::H264Encoder> encoder_;
  std::unique_ptr<video::H264Decoder> decoder_;
  mutable std::mutex mutex_;
  int requested_at_ = -1;
  int light_frames_ = 0;
};

}  // namespace cslam
