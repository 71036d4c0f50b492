// The vectorised intensity moments equal the plain loops exactly, on random and saturated patches
// and at every alignment, and the disc is ORB's radius-15 disc.
#include <cstdint>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "slam/features/patch_moments.h"

namespace {

constexpr int kW = 96, kH = 64;

void expect_equal_moments(const std::vector<std::uint8_t>& img) {
  for (int y = 16; y < kH - 16; ++y)
    for (int x = 17; x < kW - 16; ++x) {
      const std::uint8_t* c = img.data() + y * kW + x;
      const cslam::PatchMoments fast = cslam::patch_moments(c, kW), ref = cslam::patch_moments_reference(c, kW);
      ASSERT_EQ(fast.m10, ref.m10) << "at " << x << "," << y;
      ASSERT_EQ(fast.m01, ref.m01) << "at " << x << "," << y;
    }
}

}  // namespace

TEST(PatchMoments, DiscHalfWidths) {
  const int* umax = cslam::patch_row_half_widths();
  const int expected[16] = {15, 15, 15, 15, 14, 14, 14, 13,
                            13, 12, 11, 10, 9,  7,  5,  0};  // floor(sqrt(225 - v^2) + 0.5)
  for (int v = 0; v <= cslam::kPatchRadius; ++v) EXPECT_EQ(umax[v], expected[v]) << "row " << v;
}

TEST(PatchMoments, VectorisedEqualsPlainLoops) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> px(0, 255);
  std::vector<std::uint8_t> img(kW * kH);
  for (auto& p : img) p = std::uint8_t(px(rng));
  expect_equal_moments(img);
  // Saturated halves: the largest sums of each sign.
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) img[y * kW + x] = (x + y) % 2 ? 255 : 0;
  expect_equal_moments(img);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) img[y * kW + x] = x < kW / 2 ? 0 : 255;
  expect_equal_moments(img);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) img[y * kW + x] = y < kH / 2 ? 255 : 0;
  expect_equal_moments(img);
}

TEST(PatchMoments, BrightSideSetsTheSign) {
  std::vector<std::uint8_t> img(kW * kH, 0);
  for (int y = 0; y < kH; ++y)
    for (int x = kW / 2 + 1; x < kW; ++x) img[y * kW + x] = 200;  // bright right of the centre column
  const cslam::PatchMoments right = cslam::patch_moments(img.data() + (kH / 2) * kW + kW / 2, kW);
  EXPECT_GT(right.m10, 0);
  EXPECT_EQ(right.m01, 0);
  std::fill(img.begin(), img.end(), 0);
  for (int y = kH / 2 + 1; y < kH; ++y)
    for (int x = 0; x < kW; ++x) img[y * kW + x] = 200;  // bright below the centre row
  const cslam::PatchMoments below = cslam::patch_moments(img.data() + (kH / 2) * kW + kW / 2, kW);
  EXPECT_EQ(below.m10, 0);
  EXPECT_GT(below.m01, 0);
}
