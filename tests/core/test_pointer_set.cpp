// PointerSet against std::unordered_set over thousands of passes: growth within a pass, clears
// that keep the table (stale slots of earlier passes must read as empty), clears with a size hint.
#include <random>
#include <unordered_set>
#include <vector>

#include <gtest/gtest.h>

#include "core/pointer_set.h"

TEST(PointerSet, AgreesWithUnorderedSetOverManyPasses) {
  std::vector<int> storage(5000);
  std::mt19937 rng(3);
  cslam::PointerSet set;
  for (int pass = 0; pass < 3000; ++pass) {
    const std::size_t n = std::size_t(rng() % (pass % 100 == 0 ? 20000 : 300));
    set.clear(pass % 7 == 0 ? n / 4 : 0);
    std::unordered_set<const void*> ref;
    for (std::size_t k = 0; k < n; ++k) {
      const void* p = &storage[rng() % storage.size()];
      ASSERT_EQ(set.insert(p), ref.insert(p).second) << "pass " << pass;
    }
    ASSERT_EQ(set.size(), ref.size());
    for (int probe = 0; probe < 50; ++probe) {
      const void* p = &storage[rng() % storage.size()];
      ASSERT_EQ(set.contains(p), ref.count(p) > 0);
    }
  }
}

TEST(PointerSet, ClearEmptiesWithoutShrinking) {
  std::vector<int> storage(100);
  cslam::PointerSet set;
  for (int& x : storage) EXPECT_TRUE(set.insert(&x));
  EXPECT_FALSE(set.insert(&storage[5]));
  const std::size_t capacity = set.capacity();
  EXPECT_GE(capacity, storage.size());
  set.clear();
  EXPECT_EQ(set.size(), 0u);
  EXPECT_EQ(set.capacity(), capacity);
  EXPECT_FALSE(set.contains(&storage[5]));
  EXPECT_TRUE(set.insert(&storage[5]));
  EXPECT_FALSE(set.contains(nullptr));
  set.clear(1000);
  EXPECT_GE(set.capacity(), 1000u);
  EXPECT_EQ(set.size(), 0u);
}
