#pragma once
// What a lean stream (cslam-client --depth-every K) makes of one client's frames, offline: the
// first frame `request_delay` frames after tracking asked for full depth (the acks in flight),
// and otherwise the K-th frame after the last full one (frame/full_frame_clock.h, the robot's own
// rule), keeps its full depth; the others become light frames with the depth the
// server expands from every S-th pixel of every S-th row (S = light_depth; 0 or 1: none). With
// coded_colour the colour goes through the client's codecs and back as the server decodes it:
// full frames with full_colour (the client's --rgb-codec: JPEG q75 by default, or standalone
// H.264 pictures), light frames one H.264 stream per client
// (video::light_colour_stream(), only the light frames in it, as the client sends them); without
// it the colour is the dataset's, undegraded. Stepped (--sync) runs answer
// a request exactly `request_delay` frames late; threaded multi-client runs queue frames ahead of
// the workers, so there requests are answered later.
#include <memory>
#include <mutex>

#include "codec/byte_budget.h"
#include "codec/image_encoder.h"
#include "codec/keyframe_hint.h"
#include "codec/video_codec.h"
#include "frame/full_frame_clock.h"
#include "frame/rgbd_frame.h"

namespace cslam {

struct LeanStreamConfig {
  int depth_every = 1;    // 1: every frame full
  int request_delay = 0;  // the next frame: what a robot at 30 Hz measures (depth_request_lag_frames 1.0-1.07)
  int light_depth = 4;
  bool coded_colour = false;
  CodecOptions full_colour;  // full frames' colour with coded_colour (only the RGB fields are used)
  video::H264Options light_colour = video::light_colour_stream();  // light frames' stream, as the client's
  // With coded_colour: the robot's byte budget (cslam-client --byte-budget), spent on the full
  // frames' colour as the sender does; a frame counts its images' bytes and
  // ByteBudget::kHeaderBytes (the sender counts its wire messages).
  ByteBudgetConfig budget;
};

class LeanStreamSim {
 public:
  // ConfigError on depth_every < 1, request_delay < 0, light_depth outside 0..kMaxDepthSubsample
  // or invalid full_colour options.
  explicit LeanStreamSim(LeanStreamConfig config);
  // Frame n of the client (0-based): made light unless it is due to carry full depth.
  // With coded_colour, the codecs' errors pass through (InputError from a decoder).
  void apply(RgbdFrame& frame, int n);
  // Tracking of frame n asked for full depth (FrameDone::wants_depth). Thread-safe with apply().
  void requested(int n);
  // Tracking of frame n expects its next keyframe `due_in` frames later (FrameDone::keyframe_due_in;
  // 0: no hint). Thread-safe with apply().
  void keyframe_hint(int n, int due_in);
  int light_frames() const;
  int frames_finer() const;  // full frames whose colour the budget made finer

 private:
  void code_full(RgbdFrame& frame, bool spend);
  // Each returns the bytes it made (the budget counts them).
  std::size_t code_light_colour(RgbdFrame& frame);
  std::size_t make_light_depth(RgbdFrame& frame);

  const LeanStreamConfig config_;
  ImageEncoder full_images_;  // the full frames' colour (one encoder per client, as the client's)
  std::unique_ptr<video::H264Encoder> encoder_;
  std::unique_ptr<video::H264Decoder> decoder_;
  mutable std::mutex mutex_;
  int requested_at_ = -1;
  KeyframeHint hint_;
  FullFrameClock clock_;
  ByteBudget budget_;
  int light_frames_ = 0, frames_finer_ = 0;
};

}  // namespace cslam
