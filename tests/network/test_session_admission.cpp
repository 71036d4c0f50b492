// SessionTable admission rules (docs/security.md): max clients, takeover only by the owning
// connection or key (or, without CURVE, once the old connection is not active), restored sessions
// from a persisted state, reclaiming idle sessions.
#include <gtest/gtest.h>

#include "server/session_table.h"

namespace cslam::server {
namespace {

ClientInfo info(ClientId id) {
  ClientInfo i;
  i.id = id;
  return i;
}

TEST(SessionAdmission, MaxClientsAndTakeoverWithoutCurve) {
  SessionTable t(2);
  const auto t0 = Clock::now();
  EXPECT_EQ(t.admit(1, "a", ""), Admission::kNew);
  t.open(info(1), "a", t0);
  t.open(info(2), "b", t0);
  EXPECT_EQ(t.admit(3, "c", ""), Admission::kFull);
  EXPECT_EQ(t.admit(1, "a", ""), Admission::kResume);  // its own connection says hello again
  EXPECT_EQ(t.admit(1, "x", ""), Admission::kBusy);    // another peer while it is active
  t.expire(t0 + std::chrono::seconds(10), std::chrono::seconds(5));
  EXPECT_EQ(t.admit(1, "x", ""), Admission::kResume);  // timed out: it may be resumed
  t.by_client(2)->state = SessionState::kDone;
  EXPECT_EQ(t.admit(2, "y", ""), Admission::kResume);
}

TEST(SessionAdmission, WithCurveTheKeyOwnsTheSession) {
  SessionTable t(4);
  const auto t0 = Clock::now();
  t.open(info(1), "a", t0, "KEY1");
  EXPECT_EQ(t.admit(1, "b", "KEY1"), Admission::kResume);    // same key, new connection: at once
  EXPECT_EQ(t.admit(1, "b", "KEY2"), Admission::kWrongKey);  // another key, even when timed out
  t.expire(t0 + std::chrono::seconds(10), std::chrono::seconds(5));
  EXPECT_EQ(t.admit(1, "b", "KEY2"), Admission::kWrongKey);
}

TEST(SessionAdmission, RestoredSessionResumesWithItsLastSeq) {
  SessionTable t(2);
  const auto t0 = Clock::now();
  RestoredSession r;
  r.info = info(7);
  r.last_seq = 420;
  Session& s = t.restore(r, t0);
  EXPECT_EQ(s.state, SessionState::kDisconnected);
  EXPECT_THROW(t.restore(r, t0), std::invalid_argument);  // twice
  EXPECT_EQ(t.admit(7, "p", ""), Admission::kResume);
  EXPECT_EQ(t.admit(7, "p", "ANYKEY"), Admission::kResume);  // no key recorded: any key bound to the id
  auto [opened, resumed] = t.open(info(7), "p", t0, "ANYKEY");
  EXPECT_TRUE(resumed);
  EXPECT_EQ(opened->last_seq, 420u);
  EXPECT_EQ(opened->connections, 1);
  EXPECT_EQ(t.admit(7, "q", "OTHER"), Admission::kWrongKey);  // now owned by ANYKEY
  RestoredSession r2;
  r2.info = info(8);
  t.restore(r2, t0);
  RestoredSession r3;
  r3.info = info(9);
  EXPECT_THROW(t.restore(r3, t0), std::invalid_argument);  // over max clients
}

TEST(SessionAdmission, ReclaimableSessionsAreIdleAndNotActive) {
  SessionTable t(4);
  const auto t0 = Clock::now();
  t.open(info(1), "a", t0);
  t.open(info(2), "b", t0);
  t.open(info(3), "c", t0);
  t.by_client(2)->state = SessionState::kDone;
  t.by_client(3)->state = SessionState::kDisconnected;
  t.by_client(3)->in_flight = 1;  // a frame still in the worker: not yet
  const auto later = t0 + std::chrono::seconds(100);
  EXPECT_EQ(t.reclaimable(later, std::chrono::seconds(50)), std::vector<ClientId>{2});
  t.by_client(3)->in_flight = 0;
  t.by_client(3)->decoding.insert(5);  // being decoded: not yet
  EXPECT_EQ(t.reclaimable(later, std::chrono::seconds(50)), std::vector<ClientId>{2});
  EXPECT_EQ(t.by_client(3)->reserved_seq(), 5u);
  t.by_client(3)->decoding.clear();
  EXPECT_EQ(t.reclaimable(later, std::chrono::seconds(50)), (std::vector<ClientId>{2, 3}));
  EXPECT_TRUE(t.reclaimable(later, std::chrono::seconds(500)).empty());
  t.erase(2);
  t.erase(3);
  t.by_client(1)->state = SessionState::kDone;
  EXPECT_TRUE(t.all_finished(2));  // a reclaimed session that said goodbye still counts as done
  EXPECT_EQ(t.by_routing_id("b"), nullptr);
}

}  // namespace
}  // namespace cslam::server
