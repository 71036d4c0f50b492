#include "lean_sim.h"

#include <string>

#include "codec/depth_subsample.h"
#include "core/error.h"

namespace cslam {

LeanStreamSim::LeanStreamSim(LeanStreamConfig config)
    : config_(config), full_images_(config_.full_colour), budget_(config_.budget) {
  if (config_.depth_every < 1 || config_.request_delay < 0)
    throw ConfigError("--depth-every must be >= 1 and --depth-request-delay >= 0");
  if (config_.light_depth < 0 || config_.light_depth > kMaxDepthSubsample)
    throw ConfigError("--light-depth must be 0.." + std::to_string(kMaxDepthSubsample));
  if (budget_.enabled() && !config_.coded_colour) throw ConfigError("--byte-budget needs --coded-colour");
  config_.light_colour.validate();
}

void LeanStreamSim::apply(RgbdFrame& frame, int n) {
  std::lock_guard<std::mutex> lock(mutex_);
  const bool requested = n == 0 || (requested_at_ >= 0 && n > requested_at_ + config_.request_delay);
  if (clock_.next(requested, config_.depth_every)) {
    requested_at_ = -1;
    code_full(frame, hint_.on_full_frame(std::uint64_t(n), requested));
    return;
  }
  const std::size_t bytes = code_light_colour(frame) + make_light_depth(frame);
  if (budget_.enabled()) budget_.add(bytes + ByteBudget::kHeaderBytes);
  ++light_frames_;
}

void LeanStreamSim::code_full(RgbdFrame& frame, bool spend) {
  if (!config_.coded_colour) return;
  const std::size_t depth_bytes = budget_.enabled() ? full_images_.depth(frame.depth).size() : 0;
  const EncodedRgb rgb = full_images_.full_colour(frame.bgr, spend ? &budget_ : nullptr, depth_bytes);
  if (rgb.finer) ++frames_finer_;
  if (budget_.enabled()) budget_.add(rgb.bytes.size() + depth_bytes + ByteBudget::kHeaderBytes);
  frame.bgr = decode_rgb(rgb.codec, rgb.bytes.data(), rgb.bytes.size(), frame.bgr.cols, frame.bgr.rows,
                         "coded colour, frame " + std::to_string(frame.seq));
}

std::size_t LeanStreamSim::code_light_colour(RgbdFrame& frame) {
  if (!config_.coded_colour) return 0;
  const int w = frame.bgr.cols, h = frame.bgr.rows;
  if (!encoder_) {
    encoder_ = std::make_unique<video::H264Encoder>(w, h, config_.light_colour);
    decoder_ = std::make_unique<video::H264Decoder>(w, h);
  }
  const Bytes packet = encoder_->encode(frame.bgr);
  frame.bgr = decoder_->decode(packet.data(), packet.size(), "coded colour, frame " + std::to_string(frame.seq));
  return packet.size();
}

// What the server makes of a light frame's depth; its coded bytes when they count (a budget).
std::size_t LeanStreamSim::make_light_depth(RgbdFrame& frame) {
  if (config_.light_depth <= 1) {
    frame.depth = cv::Mat();
    return 0;
  }
  const cv::Mat coarse = subsample_depth(frame.depth, config_.light_depth);
  const std::size_t bytes = budget_.enabled() ? encode_depth(coarse, config_.full_colour).size() : 0;
  frame.depth = expand_depth(coarse, config_.light_depth, frame.depth.cols, frame.depth.rows);
  frame.depth_subsample = config_.light_depth;
  return bytes;
}

void LeanStreamSim::requested(int n) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (requested_at_ < 0) requested_at_ = n;
}

void LeanStreamSim::keyframe_hint(int n, int due_in) {
  std::lock_guard<std::mutex> lock(mutex_);
  hint_.on_ack(std::uint64_t(n), due_in);
}

int LeanStreamSim::light_frames() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return light_frames_;
}

int LeanStreamSim::frames_finer() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return frames_finer_;
}

}  // namespace cslam
