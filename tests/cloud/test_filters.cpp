// Voxel-grid filter (point count and centroids on a known cloud, huge extents) and
// statistical outlier removal.
#include <gtest/gtest.h>

#include "cloud/filters.h"

using namespace cslam;

namespace {

// 4 points around the centre of each voxel of an nx x ny x nz block of 1 cm voxels starting at
// voxel (ox, oy, oz), coloured by voxel.
ColoredCloud voxel_block(int nx, int ny, int nz, Eigen::Vector3i origin = {0, 0, 0}) {
  ColoredCloud c;
  const float v = 0.01f;
  const Eigen::Vector3f offs[4] = {
      {0.002f, 0.002f, 0}, {-0.002f, -0.002f, 0}, {0, 0.003f, -0.001f}, {0, -0.003f, 0.001f}};
  for (int x = 0; x < nx; ++x)
    for (int y = 0; y < ny; ++y)
      for (int z = 0; z < nz; ++z) {
        const Eigen::Vector3f centre =
            (Eigen::Vector3i(x, y, z) + origin).cast<float>() * v + Eigen::Vector3f::Constant(v / 2);
        for (int k = 0; k < 4; ++k) {
          c.points.push_back(centre + offs[k]);
          c.colors.push_back({std::uint8_t(k * 10), 100, std::uint8_t(x)});
        }
      }
  return c;
}

}  // namespace

TEST(VoxelFilter, OnePointPerOccupiedVoxelAtCentroid) {
  const ColoredCloud c = voxel_block(5, 4, 3);
  ASSERT_EQ(c.size(), 240u);
  const ColoredCloud f = voxel_filter(c, 0.01f);
  ASSERT_EQ(f.size(), 60u);
  ASSERT_EQ(f.colors.size(), 60u);
  for (size_t i = 0; i < f.size(); ++i) {
    // The four offsets sum to zero: the centroid is the voxel centre.
    const Eigen::Vector3f rel = f.points[i] / 0.01f - Eigen::Vector3f::Constant(0.5f);
    EXPECT_NEAR((rel - rel.array().round().matrix()).norm(), 0.0f, 1e-3f) << f.points[i].transpose();
    EXPECT_NEAR(f.colors[i][0], 15, 1);  // mean of 0, 10, 20, 30
    EXPECT_EQ(f.colors[i][1], 100);
  }
  // Coarser grid: 2 cm voxels aligned at 0 merge 2x2x2 blocks -> 3 x 2 x 2.
  EXPECT_EQ(voxel_filter(c, 0.02f).size(), 12u);
}

TEST(VoxelFilter, NegativeCoordinatesAndHugeExtentAreSplitNotSkipped) {
  ColoredCloud c = voxel_block(3, 3, 3, {-1, -1, -1});
  const ColoredCloud far = voxel_block(2, 2, 2, {400000, 400000, 1000});  // 4 km away: int32 index overflow
  c.append(far);
  const ColoredCloud f = voxel_filter(c, 0.01f);
  EXPECT_EQ(f.size(), 27u + 8u);
}

TEST(VoxelFilter, RejectsBadLeaf) { EXPECT_THROW(voxel_filter(voxel_block(1, 1, 1), 0.0f), std::invalid_argument); }

TEST(OutlierRemoval, RemovesIsolatedPoints) {
  ColoredCloud c;
  for (int x = 0; x < 50; ++x)
    for (int y = 0; y < 50; ++y) {
      c.points.emplace_back(0.01f * x, 0.01f * y, 0.0f);
      c.colors.push_back({1, 2, 3});
    }
  c.points.emplace_back(0.25f, 0.25f, 1.0f);
  c.colors.push_back({9, 9, 9});
  c.points.emplace_back(-2.0f, 0.0f, 0.0f);
  c.colors.push_back({9, 9, 9});
  const ColoredCloud f = remove_statistical_outliers(c, {});
  EXPECT_GE(f.size(), 2400u);
  EXPECT_LE(f.size(), 2500u);
  for (const auto& p : f.points) {
    EXPECT_LT(std::abs(p.z()), 1e-6f);
    EXPECT_GT(p.x(), -0.5f);
  }
}
