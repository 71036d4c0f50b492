// What the acks say about the link (client/link_latency.h), on latency sequences with a synthetic
// clock: the base is the smallest latency of the window, the excess the newest ack's above it,
// and calm() compares that with a margin (none for a margin of 0).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "client/link_latency.h"
#include "core/error.h"

namespace cslam::client {
namespace {

using Clock = LinkLatency::Clock;
using std::chrono::milliseconds;

TEST(LinkLatency, BeforeAnyAckTheLinkIsCalm) {
  const LinkLatency link;
  EXPECT_FALSE(link.heard());
  EXPECT_EQ(link.base_ms(), 0.0);
  EXPECT_EQ(link.excess_ms(), 0.0);
  EXPECT_TRUE(link.calm(25));
}

TEST(LinkLatency, TheExcessIsTheNewestAckAboveTheWindowsSmallest) {
  LinkLatency link(10.0);
  auto t = Clock::time_point{} + milliseconds(1);
  for (double ms : {30.0, 12.0, 18.0, 15.0}) {
    link.on_ack(ms, t);
    t += milliseconds(33);
  }
  EXPECT_TRUE(link.heard());
  EXPECT_DOUBLE_EQ(link.base_ms(), 12.0);
  EXPECT_DOUBLE_EQ(link.excess_ms(), 3.0);
  EXPECT_TRUE(link.calm(25));
  link.on_ack(60.0, t);  // a frame that waited 48 ms
  EXPECT_DOUBLE_EQ(link.excess_ms(), 48.0);
  EXPECT_FALSE(link.calm(25));
  EXPECT_TRUE(link.calm(48));
  EXPECT_TRUE(link.calm(0));  // margin 0: the link is not watched
  link.on_ack(13.0, t + milliseconds(33));
  EXPECT_TRUE(link.calm(25));
}

TEST(LinkLatency, TheBaseFollowsALinkThatGotSlower) {
  LinkLatency link(2.0);
  auto t = Clock::time_point{} + milliseconds(1);
  link.on_ack(10.0, t);
  for (int i = 0; i < 30; ++i) link.on_ack(50.0, t += milliseconds(33));  // 1 s: still within the window
  EXPECT_DOUBLE_EQ(link.base_ms(), 10.0);
  EXPECT_FALSE(link.calm(25));
  for (int i = 0; i < 45; ++i) link.on_ack(50.0, t += milliseconds(33));  // 2.5 s: the 10 ms ack left it
  EXPECT_DOUBLE_EQ(link.base_ms(), 50.0);
  EXPECT_TRUE(link.calm(25));
}

TEST(LinkLatency, ImpossibleLatenciesAndWindowsAreRefused) {
  LinkLatency link;
  const auto t = Clock::time_point{} + milliseconds(1);
  link.on_ack(20.0, t);
  link.on_ack(-5.0, t);
  link.on_ack(std::numeric_limits<double>::quiet_NaN(), t);
  EXPECT_DOUBLE_EQ(link.base_ms(), 20.0);
  EXPECT_DOUBLE_EQ(link.excess_ms(), 0.0);
  EXPECT_THROW(LinkLatency(0.0), ConfigError);
  EXPECT_THROW(LinkLatency(-1.0), ConfigError);
  EXPECT_THROW(LinkLatency(std::numeric_limits<double>::quiet_NaN()), ConfigError);
}

}  // namespace
}  // namespace cslam::client
