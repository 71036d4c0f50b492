#pragma once
// Adaptive rate of a robot's stream (SenderConfig::adapt). The sender cannot see the link, but
// it sees what the link does to its frames: the pose latency of every ack (capture -> ack) and the
// live frames it had to drop because no credit came back in time. A link that is too slow shows
// as a queue, and a queue shows as latency above the link's base (the smallest latency lately,
// which is transfer + server work without queueing) before any frame is dropped. The controller
// steps the stream down a ladder of depth_every values (full frames less often; the light frames
// between are ~10x smaller, docs/network.md) when the queue builds, and back up when the link has
// been calm a while: delay-based, like the congestion controllers of real-time video.
//
// Full frames also come whenever the server asks (a keyframe is due), so a coarser step costs
// the map nothing; it only thins out the depth tracking reads between keyframes.
#include <chrono>
#include <cstdint>
#include <deque>
#include <vector>

namespace cslam::client {

struct RateControlConfig {
  bool enabled = false;
  double margin_ms = 50;        // latency above the base that counts as a queue (1.5 frame periods at 30 Hz)
  int congested_acks = 3;       // that many acks in a row over the margin: step down
  double hold_s = 0.5;          // at most one step down per hold (the queue needs time to drain)
  double calm_s = 3.0;          // no congestion for this long, newest ack within margin / 2: step up
  double base_window_s = 10.0;  // the base is the smallest latency over this window
  int max_depth_every = 30;     // the coarsest step: one full frame a second at 30 Hz
  // Throws ConfigError on a non-positive value or max_depth_every < 2.
  void validate() const;
};

class RateController {
 public:
  using Clock = std::chrono::steady_clock;
  // start_depth_every: the configured stream (1: every frame full), the finest step.
  RateController(RateControlConfig config, int start_depth_every);

  void on_ack(double latency_ms, Clock::time_point now);
  void on_live_drop(Clock::time_point now);  // a frame replaced before a credit came: congested

  int depth_every() const { return ladder_[level_]; }
  int level() const { return int(level_); }
  std::uint64_t steps_down() const { return steps_down_; }
  std::uint64_t steps_up() const { return steps_up_; }
  double base_ms() const { return base_.empty() ? 0.0 : base_.front().second; }

 private:
  void congested(Clock::time_point now);
  void push_base(double latency_ms, Clock::time_point now);

  RateControlConfig config_;
  std::vector<int> ladder_;  // depth_every per level, finest first
  std::size_t level_ = 0;
  int over_margin_ = 0;  // consecutive acks over the margin
  Clock::time_point last_change_{}, last_congestion_{};
  // Sliding minimum of the latency: (time, latency), latencies increasing from the front.
  std::deque<std::pair<Clock::time_point, double>> base_;
  std::uint64_t steps_down_ = 0, steps_up_ = 0;
};

}  // namespace cslam::client
