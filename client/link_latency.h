#pragma once
// What a robot's acks say about its link. The pose latency of an ack (capture -> ack) is transfer
// + server work + any queue in front of the frame; its smallest value over a recent window is the
// link's base (no queue), and how far the newest ack lies above that base is the queue the link
// holds now. The rate controller (client/rate_control.h) steps the stream on it; the byte budget
// (SenderConfig::budget_link_margin_ms) spends room only while it is small, so robots that share
// a link do not fill it with finer full frames while their frames already queue.
#include <chrono>
#include <deque>
#include <utility>

namespace cslam::client {

class LinkLatency {
 public:
  using Clock = std::chrono::steady_clock;
  // window_s: how far back the base looks (the smallest latency over it). Throws ConfigError if
  // it is not positive.
  explicit LinkLatency(double window_s = 10.0);

  // Every ack with a known latency, in the order they come; a negative or NaN latency is ignored.
  void on_ack(double latency_ms, Clock::time_point now);
  bool heard() const { return !base_.empty(); }
  double base_ms() const { return base_.empty() ? 0.0 : base_.front().second; }
  // The newest ack's latency above the base (0 before any ack).
  double excess_ms() const { return excess_ms_; }
  // The link holds no queue worth margin_ms: the newest ack's excess is within it (true before
  // any ack, and for a margin <= 0: the caller does not watch the link).
  bool calm(double margin_ms) const { return margin_ms <= 0 || excess_ms_ <= margin_ms; }

 private:
  Clock::duration window_;
  // Sliding minimum: (time, latency), latencies increasing from the front.
  std::deque<std::pair<Clock::time_point, double>> base_;
  double excess_ms_ = 0;
};

}  // namespace cslam::client
