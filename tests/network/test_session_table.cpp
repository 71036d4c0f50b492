#include <gtest/gtest.h>

#include "server/session_table.h"

namespace cslam::server {
namespace {

ClientInfo info(ClientId id) {
  ClientInfo i;
  i.id = id;
  return i;
}

TEST(SessionTable, OpenResumeExpireAndFinish) {
  SessionTable t;
  const auto t0 = Clock::now();
  auto [s1, resumed1] = t.open(info(1), "peerA", t0);
  EXPECT_FALSE(resumed1);
  s1->last_seq = 10;
  EXPECT_EQ(t.by_routing_id("peerA"), s1);
  EXPECT_FALSE(t.all_finished(1));
  // Silent too long: disconnected, the session (and its last seq) is kept.
  EXPECT_EQ(t.expire(t0 + std::chrono::seconds(10), std::chrono::seconds(5)), std::vector<ClientId>{1});
  EXPECT_EQ(t.by_client(1)->state, SessionState::kDisconnected);
  EXPECT_FALSE(t.all_finished(1));  // timed out is not done
  // Same id from a new connection: resumed, old routing id forgotten.
  auto [s2, resumed2] = t.open(info(1), "peerB", t0 + std::chrono::seconds(11));
  EXPECT_TRUE(resumed2);
  EXPECT_EQ(s2->last_seq, 10u);
  EXPECT_EQ(s2->connections, 2);
  EXPECT_EQ(t.by_routing_id("peerA"), nullptr);
  EXPECT_EQ(t.by_routing_id("peerB"), s2);
  EXPECT_EQ(s2->state, SessionState::kActive);
  s2->state = SessionState::kDone;
  EXPECT_TRUE(t.all_finished(1));
  EXPECT_FALSE(t.all_finished(2));
  t.open(info(2), "peerC", t0);
  EXPECT_FALSE(t.all_finished(1));  // client 2 still active
  t.expire(t0 + std::chrono::seconds(10), std::chrono::seconds(5));
  EXPECT_TRUE(t.all_finished(1));  // it vanished: the run may end
}

TEST(SessionTable, RoutingIdText) {
  EXPECT_EQ(routing_id_text(std::string("\x00\x01k", 3)), "0001k");
  EXPECT_EQ(routing_id_text(""), "(empty)");
}

}  // namespace
}  // namespace cslam::server
