// The adaptive rate controller (client/rate_control.h) on latency sequences with a synthetic
// clock: it steps down when a queue builds, holds between steps, steps back up when calm, and
// never moves when disabled.
#include <gtest/gtest.h>

#include "client/rate_control.h"
#include "core/error.h"

namespace cslam::client {
namespace {

using Clock = RateController::Clock;
using std::chrono::milliseconds;

RateControlConfig on() {
  RateControlConfig c;
  c.enabled = true;
  return c;
}

// Feeds one ack per frame period (33 ms) with the latency of `latency(i)`; returns the time after.
template <class F>
Clock::time_point feed(RateController& r, Clock::time_point t, int acks, F latency) {
  for (int i = 0; i < acks; ++i) {
    r.on_ack(latency(i), t);
    t += milliseconds(33);
  }
  return t;
}

TEST(RateControl, ACalmLinkKeepsTheConfiguredStream) {
  RateController r(on(), 1);
  feed(r, Clock::time_point{} + milliseconds(1), 600,
       [](int i) { return 20.0 + (i % 7); });  // jitter well under the margin
  EXPECT_EQ(r.depth_every(), 1);
  EXPECT_EQ(r.steps_down(), 0u);
}

TEST(RateControl, AQueueStepsDownOncePerHoldAndCalmStepsBackUp) {
  RateController r(on(), 1);
  auto t = feed(r, Clock::time_point{} + milliseconds(1), 60, [](int) { return 20.0; });
  // A queue builds: latency climbs 10 ms per ack above the 20 ms base.
  t = feed(r, t, 15, [](int i) { return 20.0 + 10.0 * (i + 1); });  // 0.5 s
  EXPECT_EQ(r.depth_every(), 2);                                    // one step: the hold (0.5 s) keeps a second one out
  EXPECT_EQ(r.steps_down(), 1u);
  t = feed(r, t, 30, [](int) { return 300.0; });  // still queued after the hold: further down
  EXPECT_GE(r.steps_down(), 2u);
  EXPECT_LE(r.steps_down(), 3u);  // ~1 s of queue: at most one step per 0.5 s after the first
  const int coarse = r.depth_every();
  EXPECT_GE(coarse, 3);
  // The queue drains; calm for 3 s before the first step up, then one step per 3 s.
  t = feed(r, t, 80, [](int) { return 22.0; });  // 2.6 s
  EXPECT_EQ(r.depth_every(), coarse);
  t = feed(r, t, 30, [](int) { return 22.0; });  // 3.6 s in all
  EXPECT_EQ(r.steps_up(), 1u);
  EXPECT_LT(r.depth_every(), coarse);
  feed(r, t, 600, [](int) { return 22.0; });  // 20 s: back at the configured stream, not beyond
  EXPECT_EQ(r.depth_every(), 1);
  EXPECT_EQ(r.steps_up(), r.steps_down());
}

TEST(RateControl, ALiveDropIsCongestionAndTheLadderEndsAtItsTop) {
  RateControlConfig c = on();
  c.max_depth_every = 8;
  RateController r(c, 5);
  EXPECT_EQ(r.depth_every(), 5);
  auto t = Clock::time_point{} + milliseconds(1);
  for (int i = 0; i < 10; ++i, t += milliseconds(600)) r.on_live_drop(t);
  EXPECT_EQ(r.depth_every(), 8);  // 5 -> 8, the top
  EXPECT_EQ(r.steps_down(), 1u);
}

TEST(RateControl, TheBaseIsTheSmallestLatencyOfTheWindow) {
  RateController r(on(), 1);
  auto t = feed(r, Clock::time_point{} + milliseconds(1), 10, [](int) { return 15.0; });
  t = feed(r, t, 100, [](int) { return 40.0; });  // 3.3 s
  EXPECT_DOUBLE_EQ(r.base_ms(), 15.0);
  feed(r, t, 250, [](int) { return 40.0; });  // past the 10 s window: the base follows the link
  EXPECT_DOUBLE_EQ(r.base_ms(), 40.0);
  EXPECT_EQ(r.steps_down(), 0u);  // 25 ms over the base is within the margin
}

TEST(RateControl, DisabledNeverMovesAndBadConfigIsRefused) {
  RateController r(RateControlConfig{}, 1);
  auto t = feed(r, Clock::time_point{} + milliseconds(1), 100, [](int i) { return 20.0 + 50.0 * i; });
  r.on_live_drop(t);
  EXPECT_EQ(r.depth_every(), 1);
  EXPECT_EQ(r.steps_down(), 0u);
  RateControlConfig bad = on();
  bad.margin_ms = 0;
  EXPECT_THROW(RateController(bad, 1), ConfigError);
  bad = on();
  bad.max_depth_every = 1;
  EXPECT_THROW(RateController(bad, 1), ConfigError);
  EXPECT_THROW(RateController(on(), 0), ConfigError);
}

}  // namespace
}  // namespace cslam::client
