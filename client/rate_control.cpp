#include "client/rate_control.h"

#include <string>

#include "core/error.h"

namespace cslam::client {

void RateControlConfig::validate() const {
  if (!(margin_ms > 0) || congested_acks < 1 || !(hold_s > 0) || !(calm_s > 0) || !(base_window_s > 0))
    throw ConfigError("rate control: margin, congested acks, hold, calm and base window must be positive");
  if (max_depth_every < 2 || max_depth_every > 1000)
    throw ConfigError("rate control: max_depth_every " + std::to_string(max_depth_every) + " out of range 2..1000");
}

RateController::RateController(RateControlConfig config, int start_depth_every) : config_(config) {
  if (config_.enabled) config_.validate();
  if (start_depth_every < 1) throw ConfigError("rate control: start depth_every must be >= 1");
  ladder_.push_back(start_depth_every);
  // Roughly x1.6 per step: each step cuts the full frames' share of the bytes by about a third.
  for (int k : {2, 3, 5, 8, 12, 20, 30, 50, 80, 120, 200, 300, 500, 1000})
    if (k > ladder_.back() && k <= config_.max_depth_every) ladder_.push_back(k);
}

void RateController::push_base(double latency_ms, Clock::time_point now) {
  while (!base_.empty() && base_.back().second >= latency_ms) base_.pop_back();
  base_.emplace_back(now, latency_ms);
  const auto window = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(config_.base_window_s));
  while (base_.size() > 1 && now - base_.front().first > window) base_.pop_front();
}

void RateController::congested(Clock::time_point now) {
  last_congestion_ = now;
  over_margin_ = 0;
  if (level_ + 1 >= ladder_.size()) return;
  if (steps_down_ + steps_up_ > 0 && now - last_change_ < std::chrono::duration<double>(config_.hold_s)) return;
  ++level_;
  ++steps_down_;
  last_change_ = now;
}

void RateController::on_ack(double latency_ms, Clock::time_point now) {
  if (!config_.enabled || !(latency_ms >= 0)) return;
  if (last_change_ == Clock::time_point{}) last_change_ = last_congestion_ = now;  // the first ack starts the clocks
  push_base(latency_ms, now);
  const double excess = latency_ms - base_ms();
  over_margin_ = excess > config_.margin_ms ? over_margin_ + 1 : 0;
  if (over_margin_ >= config_.congested_acks) {
    congested(now);
    return;
  }
  const auto calm = std::chrono::duration<double>(config_.calm_s);
  if (level_ > 0 && excess <= config_.margin_ms / 2 && now - last_congestion_ >= calm && now - last_change_ >= calm) {
    --level_;
    ++steps_up_;
    last_change_ = now;
  }
}

void RateController::on_live_drop(Clock::time_point now) {
  if (!config_.enabled) return;
  if (last_change_ == Clock::time_point{}) last_change_ = last_congestion_ = now;
  congested(now);
}

}  // namespace cslam::client
