#include "client/link_latency.h"

#include <string>

#include "core/error.h"

namespace cslam::client {

LinkLatency::LinkLatency(double window_s) {
  if (!(window_s > 0)) throw ConfigError("link latency window " + std::to_string(window_s) + " s must be positive");
  window_ = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(window_s));
}

void LinkLatency::on_ack(double latency_ms, Clock::time_point now) {
  if (!(latency_ms >= 0)) return;
  while (!base_.empty() && base_.back().second >= latency_ms) base_.pop_back();
  base_.emplace_back(now, latency_ms);
  while (base_.size() > 1 && now - base_.front().first > window_) base_.pop_front();
  excess_ms_ = latency_ms - base_ms();
}

}  // namespace cslam::client
