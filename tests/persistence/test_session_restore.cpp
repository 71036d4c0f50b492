// Sessions restored from a snapshot: known and disconnected until their client says hello, which
// resumes them with the restored last_seq; they do not hold an --exit-when-done run open.
#include <gtest/gtest.h>

#include "server/session_table.h"

namespace cslam::server {
namespace {

TEST(SessionRestore, RestoredSessionResumesAtHelloWithItsLastSeq) {
  SessionTable t;
  const auto t0 = Clock::now();
  ClientInfo info;
  info.id = 7;
  info.name = "robot7";
  t.restore(info, 412, t0);
  ASSERT_NE(t.by_client(7), nullptr);
  EXPECT_EQ(t.by_client(7)->state, SessionState::kDisconnected);
  EXPECT_EQ(t.by_client(7)->last_seq, 412u);
  EXPECT_EQ(t.by_client(7)->in_flight, 0u);
  EXPECT_FALSE(t.all_finished(1));  // nobody done yet, and a restored session is not active
  auto [s, resumed] = t.open(info, "peerA", t0 + std::chrono::seconds(1));
  EXPECT_TRUE(resumed);
  EXPECT_EQ(s->last_seq, 412u);
  EXPECT_EQ(s->state, SessionState::kActive);
  EXPECT_EQ(t.by_routing_id("peerA"), s);
}

}  // namespace
}  // namespace cslam::server
