// Navigation maps of the synthetic room against its exact geometry: TSDF submaps integrated
// from rendered frames with ground-truth poses (world = the first camera's frame), up and floor
// estimated, the 2D grid compared with the exact occupancy of the band, the .bt read back with
// OctoMap's own reader.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include "navmap/map_server_io.h"
#include "navmap/nav_maps.h"
#include "synthetic_dense_map.h"

using namespace cslam;

namespace {

// 2D distance from a floor point to the nearest obstacle of the band (0 inside one): outside
// the room and every piece of furniture (all stand on the floor and are >= 0.35 m tall).
double obstacle_distance(const synth::Scene& s, const Eigen::Vector2d& q) {
  const double W = s.config.width, D = s.config.depth;
  if (q.x() <= 0 || q.y() <= 0 || q.x() >= W || q.y() >= D) return 0;
  double d = std::min({q.x(), W - q.x(), q.y(), D - q.y()});
  for (const synth::Furniture& f : s.furniture) d = std::min(d, f.footprint_distance(q));
  return d;
}

class NavMapScene : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    fixture_ = new test::DenseFixture(test::make_dense_fixture({}));
    maps_ = new NavMaps(build_nav_maps(fixture_->views, fixture_->T_world_cams, NavMapConfig{}));
  }
  static void TearDownTestSuite() {
    delete maps_;
    delete fixture_;
  }
  static test::DenseFixture* fixture_;
  static NavMaps* maps_;
};
test::DenseFixture* NavMapScene::fixture_ = nullptr;
NavMaps* NavMapScene::maps_ = nullptr;

}  // namespace

TEST_F(NavMapScene, UpAndFloorEstimated) {
  const NavMaps& m = *maps_;
  EXPECT_TRUE(m.up_estimated);
  EXPECT_EQ(m.floor_rule, "peak");
  const Eigen::Vector3d up_scene = fixture_->T_scene_world.R() * m.up;
  const double angle_deg = std::acos(std::min(1.0, up_scene.z())) * 180.0 / M_PI;
  std::printf("up error %.3f deg, floor samples %zu\n", angle_deg, m.stats.floor_samples);
  EXPECT_LT(angle_deg, 3.0);
  // Height of the true floor (z = 0) above the estimated floor plane, at the room's centre and corners.
  const SE3 T_world_scene = fixture_->T_scene_world.inverse();
  const double W = fixture_->scene.config.width, D = fixture_->scene.config.depth;
  const double centre = m.up.dot(T_world_scene * Eigen::Vector3d(W / 2, D / 2, 0)) - m.floor;
  std::printf("floor offset at the room centre %.4f m\n", centre);
  EXPECT_LT(std::abs(centre), 0.02);
  for (double x : {0.0, W})
    for (double y : {0.0, D}) EXPECT_LT(std::abs(m.up.dot(T_world_scene * Eigen::Vector3d(x, y, 0)) - m.floor), 0.08);
}

TEST_F(NavMapScene, GridAgreesWithExactScene) {
  const NavMaps& m = *maps_;
  ASSERT_TRUE(m.grid_error.empty()) << m.grid_error;
  const OccupancyGrid2D& g = m.grid;
  ASSERT_FALSE(g.empty());
  ASSERT_EQ(g.cells.size(), std::size_t(g.width) * std::size_t(g.height));
  const double half_diag = g.resolution * std::sqrt(0.5);
  std::size_t observed = 0, boundary = 0, judged = 0, agree = 0, centre_agree = 0, occupied = 0, free = 0;
  std::size_t false_free = 0, false_occupied = 0;
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const std::int8_t v = g.at(i, j);
      if (v == OccupancyGrid2D::kUnknown) continue;
      ASSERT_TRUE(v == OccupancyGrid2D::kFree || v == OccupancyGrid2D::kOccupied);
      ++observed;
      (v == OccupancyGrid2D::kOccupied ? occupied : free) += 1;
      const Eigen::Vector3d p = fixture_->T_scene_world * g.cell_center_world(i, j);
      const double d = obstacle_distance(fixture_->scene, p.head<2>());
      const bool map_occ = v == OccupancyGrid2D::kOccupied;
      centre_agree += map_occ == (d <= 0);
      if (d > 0 && d <= half_diag) {  // an obstacle's edge runs through the cell: either answer is right
        ++boundary;
        continue;
      }
      ++judged;
      agree += map_occ == (d <= 0);
      false_free += !map_occ && d <= 0;
      false_occupied += map_occ && d > 0;
    }
  const double agreement = double(agree) / double(std::max<std::size_t>(1, judged));
  std::printf(
      "grid %d x %d at %.2f m: observed %zu (occupied %zu, free %zu), edge cells %zu; agreement %.2f %% of %zu "
      "non-edge observed cells, %.2f %% of all observed cells by their centres; %.1f ms (up/floor %.1f, grid %.1f, "
      "octomap %.1f)\n",
      g.width, g.height, g.resolution, observed, occupied, free, boundary, 100 * agreement, judged,
      100.0 * double(centre_agree) / double(std::max<std::size_t>(1, observed)), m.stats.total_ms, m.stats.up_floor_ms,
      m.stats.grid_ms, m.stats.octomap_ms);
  std::printf("disagreements: %zu free cells inside an obstacle, %zu occupied cells clear of any obstacle\n",
              false_free, false_occupied);
  EXPECT_GT(occupied, 500u);
  EXPECT_GT(free, 500u);
  EXPECT_GE(agreement, 0.95);
  EXPECT_EQ(m.stats.cells_occupied, occupied);
  EXPECT_EQ(m.stats.cells_free, free);
}

TEST_F(NavMapScene, GridFrameSitsOnTheFloor) {
  const OccupancyGrid2D& g = maps_->grid;
  ASSERT_FALSE(g.empty());
  const Eigen::Matrix3d R = g.T_world_grid.R();
  EXPECT_LT((R.col(2) - maps_->up).norm(), 1e-9);                                // z is up
  EXPECT_NEAR(maps_->up.dot(g.T_world_grid.translation()), maps_->floor, 1e-9);  // origin on the floor
  EXPECT_NEAR(maps_->up.dot(g.cell_center_world(g.width - 1, g.height - 1)), maps_->floor, 1e-9);
  // The map_server files describe the same grid.
  const std::string pgm = to_pgm(g);
  const std::string header = "P5\n" + std::to_string(g.width) + " " + std::to_string(g.height) + "\n255\n";
  ASSERT_EQ(pgm.size(), header.size() + g.cells.size());
  EXPECT_EQ(pgm.compare(0, header.size(), header), 0);
}

TEST_F(NavMapScene, OctomapLoadsWithOctomapsReaderAndLiesOnTheScene) {
  const NavMaps& m = *maps_;
  ASSERT_TRUE(m.octomap_error.empty()) << m.octomap_error;
  ASSERT_FALSE(m.octomap_bt.empty());
  // Through a file, as another tool would read it.
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("cslam-navmap-" + std::to_string(::getpid()) + ".bt");
  {
    std::ofstream out(path, std::ios::binary);
    out.write(m.octomap_bt.data(), std::streamsize(m.octomap_bt.size()));
  }
  octomap::OcTree from_file(0.1);
  EXPECT_TRUE(from_file.readBinary(path.string()));
  std::filesystem::remove(path);
  EXPECT_NEAR(from_file.getResolution(), 0.05, 1e-12);

  octomap::OcTree tree(0.1);
  std::istringstream in(m.octomap_bt);
  ASSERT_TRUE(tree.readBinary(in));
  EXPECT_EQ(tree.size(), from_file.size());
  EXPECT_EQ(tree.size(), m.stats.octree_nodes);
  std::size_t occ = 0, occ_ok = 0, fr = 0, fr_ok = 0, leaves = 0;
  const double trunc = fixture_->volumes.front()->config().truncation;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it, ++leaves) {
    if (leaves % 7 != 0) continue;  // a sample
    const Eigen::Vector3d p = fixture_->T_scene_world * Eigen::Vector3d(it.getX(), it.getY(), it.getZ());
    const double reach = it.getSize() * std::sqrt(3.0) / 2;
    if (tree.isNodeOccupied(*it)) {
      ++occ;
      occ_ok += fixture_->scene.distance_to_surface(p) <= reach + trunc;
    } else {
      ++fr;
      fr_ok += fixture_->scene.is_free(p) || fixture_->scene.distance_to_surface(p) <= reach;
    }
  }
  std::printf(
      "octree: %zu nodes, %zu leaves; sampled occupied %zu (%.2f %% on a surface), free %zu (%.2f %% in free space)\n",
      tree.size(), leaves, occ, 100.0 * occ_ok / std::max<std::size_t>(1, occ), fr,
      100.0 * fr_ok / std::max<std::size_t>(1, fr));
  EXPECT_GT(occ, 100u);
  EXPECT_GT(fr, 100u);
  EXPECT_GE(double(occ_ok), 0.97 * double(occ));
  EXPECT_GE(double(fr_ok), 0.97 * double(fr));
}
