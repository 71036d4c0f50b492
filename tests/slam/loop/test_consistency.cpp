// ConsistencyChecker: a candidate is returned on the 3rd consecutive consistent update.
#include <gtest/gtest.h>

#include "core/error.h"
#include "slam/loop/consistency.h"

using namespace cslam;

namespace {

KeyFrameId kf(std::uint32_t seq, ClientId client = 0) { return KeyFrameId{client, seq}; }

ConsistencyChecker::Group group(std::uint32_t candidate, std::vector<std::uint32_t> covisible, ClientId client = 0) {
  ConsistencyChecker::Group g;
  g.candidate = kf(candidate, client);
  for (auto s : covisible) g.members.push_back(kf(s, client));
  return g;
}

}  // namespace

TEST(Consistency, ReturnedExactlyOnThirdConsecutiveCall) {
  ConsistencyChecker c;
  EXPECT_TRUE(c.update({group(10, {9, 11})}).empty());
  EXPECT_TRUE(c.update({group(10, {9, 11})}).empty());
  const auto out = c.update({group(10, {9, 11})});
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0], kf(10));
  // Still consistent on the next update (a failed geometric check can be retried).
  EXPECT_EQ(c.update({group(10, {9, 11})}).size(), 1u);
  c.reset();
  EXPECT_TRUE(c.update({group(10, {9, 11})}).empty());
}

TEST(Consistency, ContinuedThroughSharedCovisiblesNotOnlyTheSameCandidate) {
  ConsistencyChecker c;
  EXPECT_TRUE(c.update({group(10, {9, 11})}).empty());
  EXPECT_TRUE(c.update({group(12, {11, 13})}).empty());  // shares kf 11
  const auto out = c.update({group(14, {13, 15})});      // shares kf 13
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0], kf(14));
  EXPECT_EQ(c.tracked().at(0).count, 3);
}

TEST(Consistency, InconsistentSequencesNeverReturn) {
  ConsistencyChecker c;
  for (std::uint32_t i = 0; i < 10; ++i) EXPECT_TRUE(c.update({group(100 * i, {100 * i + 1})}).empty()) << i;
  // Same seq in another client is another keyframe.
  for (ClientId client = 0; client < 5; ++client) EXPECT_TRUE(c.update({group(7, {8}, client)}).empty());
}

TEST(Consistency, AGapOrAnEmptyUpdateRestartsTheCount) {
  ConsistencyChecker c;
  EXPECT_TRUE(c.update({group(10, {11})}).empty());
  EXPECT_TRUE(c.update({group(10, {11})}).empty());
  EXPECT_TRUE(c.update({}).empty());  // no candidates for this query: groups dropped
  EXPECT_TRUE(c.update({group(10, {11})}).empty());
  EXPECT_TRUE(c.update({group(10, {11})}).empty());
  EXPECT_EQ(c.update({group(10, {11})}).size(), 1u);
  // An unrelated group in between also breaks it.
  ConsistencyChecker d;
  d.update({group(1, {2})});
  d.update({group(1, {2})});
  d.update({group(50, {51})});
  EXPECT_TRUE(d.update({group(1, {2})}).empty());
}

TEST(Consistency, SeveralGroupsTrackedIndependently) {
  ConsistencyChecker c;
  c.update({group(10, {11}), group(40, {41})});
  c.update({group(10, {11}), group(60, {61})});  // 40's line breaks, 60 starts
  const auto out = c.update({group(11, {12}), group(40, {41}), group(60, {61})});
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0], kf(11));
  const auto out2 = c.update({group(60, {61}), group(11, {10}), group(61, {60})});
  // 60's line reaches 3, 11's continues at 4, 61 shares kf 60/61 with 60's line (also 3).
  ASSERT_EQ(out2.size(), 3u);
  EXPECT_EQ(out2[0], kf(60));
  EXPECT_EQ(out2[1], kf(11));
  EXPECT_EQ(out2[2], kf(61));
}

TEST(Consistency, RequiredIsConfigurable) {
  ConsistencyChecker one(1);
  EXPECT_EQ(one.update({group(3, {})}).size(), 1u);  // members may be empty: the candidate counts
  ConsistencyChecker four(4);
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(four.update({group(3, {4})}).empty());
  EXPECT_EQ(four.update({group(3, {4})}).size(), 1u);
  EXPECT_THROW(ConsistencyChecker(0), ConfigError);
}
