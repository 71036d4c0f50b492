#include <sstream>
#include <unordered_set>

#include <gtest/gtest.h>

#include "core/ids.h"

TEST(Ids, CarryClientAndHash) {
  cslam::KeyFrameId a{1, 5}, b{2, 5}, c{1, 5};
  EXPECT_NE(a, b);
  EXPECT_EQ(a, c);
  EXPECT_TRUE(a < b);
  std::unordered_set<cslam::KeyFrameId> set{a, b, c};
  EXPECT_EQ(set.size(), 2u);
  std::ostringstream os;
  os << b;
  EXPECT_EQ(os.str(), "kf2:5");
}
