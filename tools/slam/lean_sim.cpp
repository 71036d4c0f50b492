#include "lean_sim.h"

#include <string>

#include "codec/depth_subsample.h"
#include "core/error.h"

namespace cslam {

LeanStreamSim::LeanStreamSim(LeanStreamConfig config) : config_(config), full_images_(config_.full_colour) {
  if (config_.depth_every < 1 || config_.request_delay < 0)
    throw ConfigError("--depth-every must be >= 1 and --depth-request-delay >= 0");
  if (config_.light_depth < 0 || config_.light_depth > kMaxDepthSubsample)
    throw ConfigError("--light-depth must be 0.." + std::to_string(kMaxDepthSubsample));
  config_.light_colour.validate();
}

void LeanStreamSim::apply(RgbdFrame& frame, int n) {
  std::lock_guard<std::mutex> lock(mutex_);
  const bool requested = n == 0 || (requested_at_ >= 0 && n > requested_at_ + config_.request_delay);
  if (clock_.next(requested, config_.depth_every)) {
    requested_at_ = -1;
    code_colour(frame, true);
    return;
  }
  code_colour(frame, false);
  if (config_.light_depth > 1) {  // what the server makes of a light frame's depth
    frame.depth = expand_depth(subsample_depth(frame.depth, config_.light_depth), config_.light_depth, frame.depth.cols,
                               frame.depth.rows);
    frame.depth_subsample = config_.light_depth;
  } else {
    frame.depth = cv::Mat();
  }
  ++light_frames_;
}

void LeanStreamSim::code_colour(RgbdFrame& frame, bool full) {
  if (!config_.coded_colour) return;
  const int w = frame.bgr.cols, h = frame.bgr.rows;
  const std::string source = "coded colour, frame " + std::to_string(frame.seq);
  if (full) {
    const Bytes bytes = full_images_.rgb(frame.bgr);
    frame.bgr = decode_rgb(config_.full_colour.rgb, bytes.data(), bytes.size(), w, h, source);
    return;
  }
  if (!encoder_) {
    encoder_ = std::make_unique<video::H264Encoder>(w, h, config_.light_colour);
    decoder_ = std::make_unique<video::H264Decoder>(w, h);
  }
  const Bytes packet = encoder_->encode(frame.bgr);
  frame.bgr = decoder_->decode(packet.data(), packet.size(), source);
}

void LeanStreamSim::requested(int n) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (requested_at_ < 0) requested_at_ = n;
}

int LeanStreamSim::light_frames() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return light_frames_;
}

}  // namespace cslam
