// Navigation maps on hand-made input: map_server files of a tiny grid, the up and floor rules,
// a floor seen from above with noisy pixels and a real obstacle, bad input and budgets.
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include "common/small_camera.h"
#include "core/error.h"
#include "navmap/map_server_io.h"
#include "navmap/nav_maps.h"

using namespace cslam;

namespace {

OccupancyGrid2D tiny_grid() {
  OccupancyGrid2D g;
  g.width = 3;
  g.height = 2;
  g.resolution = 0.1;
  g.T_world_grid = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 2, 3));
  g.cells = {0,   100, -1,  // row 0 (grid y = 0, bottom)
             100, -1,  0};  // row 1 (top)
  return g;
}

std::map<std::string, std::string> yaml_fields(const std::string& yaml) {
  std::map<std::string, std::string> out;
  std::istringstream in(yaml);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    out[line.substr(0, colon)] = line.substr(colon + 2);
  }
  return out;
}

using test::small_camera;

// A camera 1.2 m above a floor (z = 0, z up) looking straight down; depth per pixel.
struct TopDown {
  PinholeCamera cam = small_camera();
  SE3 T_world_cam{(Eigen::Matrix3d() << 1, 0, 0, 0, -1, 0, 0, 0, -1).finished(), Eigen::Vector3d(0, 0, 1.2)};
  cv::Mat depth = cv::Mat(cam.height, cam.width, CV_16UC1, cv::Scalar(1.2 * 5000));
  cv::Mat bgr = cv::Mat(cam.height, cam.width, CV_8UC3, cv::Scalar(90, 90, 90));
  std::unique_ptr<TsdfVolume> integrate(float voxel = 0.01f) const {
    TsdfConfig tc;
    tc.voxel_size = voxel;
    tc.truncation = 4 * voxel;
    tc.stride = 1;
    auto vol = std::make_unique<TsdfVolume>(tc);
    vol->integrate(bgr, depth, RayTable(cam), SE3(), 0.3, 4.0);  // volume in the camera frame
    return vol;
  }
  // World point seen at pixel (u, v) at depth z.
  Eigen::Vector3d point(int u, int v, double z) const { return T_world_cam * cam.unproject(u, v, z); }
};

NavMapConfig z_up() {
  NavMapConfig c;
  c.up = Eigen::Vector3d(0, 0, 1);
  return c;
}

// The grid cell holding world point p (column, row), or (-1, -1) outside.
std::pair<int, int> cell_of(const OccupancyGrid2D& g, const Eigen::Vector3d& p) {
  const Eigen::Vector3d q = g.T_world_grid.inverse() * p;
  const int i = int(std::floor(q.x() / g.resolution)), j = int(std::floor(q.y() / g.resolution));
  if (i < 0 || j < 0 || i >= g.width || j >= g.height) return {-1, -1};
  return {i, j};
}

}  // namespace

TEST(NavMapFiles, PgmValuesAndRowFlip) {
  const std::string pgm = to_pgm(tiny_grid());
  const std::string header = "P5\n3 2\n255\n";
  ASSERT_EQ(pgm.size(), header.size() + 6);
  EXPECT_EQ(pgm.substr(0, header.size()), header);
  const std::string px = pgm.substr(header.size());
  // Image row 0 = grid row 1 (top): occupied, unknown, free; then grid row 0: free, occupied, unknown.
  const unsigned char expect[6] = {0, 205, 254, 254, 0, 205};
  for (int k = 0; k < 6; ++k) EXPECT_EQ((unsigned char)px[size_t(k)], expect[k]) << k;
  EXPECT_EQ(to_pgm(OccupancyGrid2D{}), "P5\n0 0\n255\n");
}

TEST(NavMapFiles, YamlFields) {
  const auto f = yaml_fields(to_map_yaml(tiny_grid(), "occupancy.pgm"));
  EXPECT_EQ(f.at("image"), "\"occupancy.pgm\"");
  EXPECT_DOUBLE_EQ(std::stod(f.at("resolution")), 0.1);
  EXPECT_EQ(f.at("origin"), "[0.0, 0.0, 0.0]");
  EXPECT_EQ(f.at("negate"), "0");
  EXPECT_DOUBLE_EQ(std::stod(f.at("occupied_thresh")), 0.65);
  EXPECT_DOUBLE_EQ(std::stod(f.at("free_thresh")), 0.196);
  EXPECT_EQ(f.at("mode"), "trinary");
  // The grid's pose in the world is in a comment; a hostile file name cannot break the YAML.
  EXPECT_NE(to_map_yaml(tiny_grid(), "x").find("# T_world_grid: [1, 2, 3, 0, 0, 0, 1]"), std::string::npos);
  EXPECT_EQ(yaml_fields(to_map_yaml(tiny_grid(), "a\"\nnegate: 1")).at("negate"), "0");
}

TEST(NavMapUp, MeanOfCameraYAxesAndFallback) {
  const Eigen::Vector3d fallback(0, -1, 0);
  // Cameras level in a z-up world (y axis = -z), yawed and pitched a little both ways.
  std::vector<SE3> cams;
  for (int k = 0; k < 8; ++k) {
    const double yaw = k * M_PI / 4, pitch = (k % 2 ? 1 : -1) * 0.08;
    const Eigen::Matrix3d level = (Eigen::Matrix3d() << 0, 0, 1, -1, 0, 0, 0, -1, 0).finished();  // cam z -> world x
    const Eigen::Matrix3d R = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() * level *
                              Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()).toRotationMatrix();
    cams.emplace_back(R, Eigen::Vector3d(k, 0, 1));
  }
  UpEstimate up = estimate_up(cams, fallback);
  EXPECT_TRUE(up.from_cameras);
  EXPECT_LT((up.up - Eigen::Vector3d::UnitZ()).norm(), 1e-6);
  // A NaN pose is counted and skipped.
  cams.emplace_back(Eigen::Quaterniond(std::nan(""), 0, 0, 1), Eigen::Vector3d::Zero());
  up = estimate_up(cams, fallback);
  EXPECT_EQ(up.cameras_skipped, 1u);
  EXPECT_EQ(up.cameras_used, 8u);
  EXPECT_LT((up.up - Eigen::Vector3d::UnitZ()).norm(), 1e-6);
  // No camera, or cameras that disagree: the default.
  EXPECT_FALSE(estimate_up({}, fallback).from_cameras);
  EXPECT_EQ(estimate_up({}, Eigen::Vector3d(0, -2, 0)).up, fallback);
  const SE3 a, b(Eigen::Matrix3d(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ())), Eigen::Vector3d::Zero());
  EXPECT_FALSE(estimate_up({a, b}, fallback).from_cameras);
  EXPECT_THROW(estimate_up({a}, Eigen::Vector3d::Zero()), ConfigError);
}

TEST(NavMapFloor, LowestDenseClusterIgnoresOutliersBelow) {
  std::vector<double> h;
  for (int k = 0; k < 1000; ++k) h.push_back(0.3 + 0.001 * (k % 7));  // floor at ~0.303
  for (int k = 0; k < 600; ++k) h.push_back(1.05 + 0.001 * (k % 5));  // a table top
  for (int k = 0; k < 20; ++k) h.push_back(-0.5 + 0.03 * k);          // outliers below
  h.push_back(std::numeric_limits<double>::quiet_NaN());
  std::size_t n = 0;
  const auto f = floor_from_heights(h, 0.01, 0.05, &n);
  ASSERT_TRUE(f);
  EXPECT_NEAR(*f, 0.303, 0.003);
  EXPECT_EQ(n, 1000u);
  EXPECT_FALSE(floor_from_heights({}, 0.01, 0.05));
}

TEST(NavMapGrid, NoisyPixelsDoNotBlockAFreeFloorButATopDoes) {
  TopDown scene;
  // Five isolated noisy pixels 0.6 m above the floor, and a 14 x 14 pixel box top at 0.6 m.
  const int noisy[5][2] = {{20, 20}, {40, 90}, {120, 30}, {140, 100}, {60, 60}};
  for (const auto& p : noisy) scene.depth.at<std::uint16_t>(p[1], p[0]) = std::uint16_t(0.6 * 5000);
  scene.depth(cv::Rect(100, 60, 14, 14)).setTo(cv::Scalar(0.6 * 5000));
  const auto vol = scene.integrate();
  const SubmapViews views{{vol.get(), scene.T_world_cam}};
  const NavMaps m = build_nav_maps(views, {}, z_up());
  EXPECT_EQ(m.floor_rule, "peak");
  EXPECT_NEAR(m.floor, 0.0, 0.01);
  ASSERT_FALSE(m.grid.empty()) << m.grid_error;
  for (const auto& p : noisy) {
    const auto [i, j] = cell_of(m.grid, scene.point(p[0], p[1], 1.2));
    ASSERT_GE(i, 0);
    EXPECT_EQ(m.grid.at(i, j), OccupancyGrid2D::kFree) << p[0] << "," << p[1];
  }
  const auto [bi, bj] = cell_of(m.grid, scene.point(107, 67, 0.6));
  ASSERT_GE(bi, 0);
  EXPECT_EQ(m.grid.at(bi, bj), OccupancyGrid2D::kOccupied);
  // Only the box top's cells are occupied (its 8.4 cm square covers at most 3 x 3 cells).
  EXPECT_GE(m.stats.cells_occupied, 1u);
  EXPECT_LE(m.stats.cells_occupied, 9u);
  EXPECT_GT(m.stats.cells_free, 200u);
}

TEST(NavMapGrid, SubmapsVoteAsLogOdds) {
  TopDown clear, blocked;
  blocked.depth(cv::Rect(60, 40, 40, 40)).setTo(cv::Scalar(0.6 * 5000));  // a 24 cm box top at 0.6 m
  const auto a = clear.integrate(), b = blocked.integrate(), c = clear.integrate(), d = clear.integrate();
  const Eigen::Vector3d box = blocked.point(80, 60, 0.6);
  auto box_cell = [&](const SubmapViews& v) {
    const NavMaps m = build_nav_maps(v, {}, z_up());
    const auto [i, j] = cell_of(m.grid, box);
    return m.grid.at(i, j);
  };
  const SE3 T = clear.T_world_cam;
  EXPECT_EQ(box_cell({{b.get(), T}}), OccupancyGrid2D::kOccupied);
  EXPECT_EQ(box_cell({{b.get(), T}, {a.get(), T}}), OccupancyGrid2D::kOccupied);  // +0.85 - 0.405
  EXPECT_EQ(box_cell({{b.get(), T}, {a.get(), T}, {c.get(), T}, {d.get(), T}}), OccupancyGrid2D::kFree);  // outvoted
}

TEST(NavMapBadInput, EmptyUnobservedAndNanNeverCrash) {
  NavMaps m = build_nav_maps({}, {}, NavMapConfig{});
  EXPECT_TRUE(m.grid.empty());
  EXPECT_TRUE(m.octomap_bt.empty());
  EXPECT_EQ(m.floor_rule, "none");
  EXPECT_FALSE(m.grid_error.empty());

  TsdfVolume unobserved{TsdfConfig{}};
  const SE3 nan_pose(Eigen::Quaterniond(1, 0, 0, 0), Eigen::Vector3d(std::nan(""), 0, 0));
  m = build_nav_maps({{&unobserved, SE3()}, {nullptr, SE3()}, {&unobserved, nan_pose}}, {nan_pose}, NavMapConfig{});
  EXPECT_TRUE(m.grid.empty());
  EXPECT_EQ(m.floor_rule, "none");
  EXPECT_EQ(m.stats.submaps_used, 1u);
  EXPECT_EQ(m.stats.submaps_skipped, 2u);
  EXPECT_EQ(m.stats.cameras_skipped, 1u);

  // A real submap next to a NaN-posed one: the NaN one is skipped, the maps are made.
  TopDown scene;
  const auto vol = scene.integrate(0.02f);
  m = build_nav_maps({{vol.get(), scene.T_world_cam}, {vol.get(), nan_pose}}, {}, z_up());
  EXPECT_FALSE(m.grid.empty());
  EXPECT_FALSE(m.octomap_bt.empty());
  EXPECT_EQ(m.stats.submaps_skipped, 1u);
  // Given floor and up are used as given.
  NavMapConfig given = z_up();
  given.floor_height = -0.25;
  m = build_nav_maps({{vol.get(), scene.T_world_cam}}, {}, given);
  EXPECT_EQ(m.floor_rule, "given");
  EXPECT_DOUBLE_EQ(m.floor, -0.25);
  EXPECT_DOUBLE_EQ(m.grid.T_world_grid.translation().z(), -0.25);
}

TEST(NavMapBadInput, BudgetsRefuse) {
  TopDown scene;
  const auto vol = scene.integrate(0.02f);
  // Two copies of the floor a million metres apart: a grid far beyond the cell budget.
  const SE3 far(scene.T_world_cam.rotation(), scene.T_world_cam.translation() + Eigen::Vector3d(1e6, 0, 0));
  NavMapConfig c = z_up();
  c.octomap = false;
  NavMaps m = build_nav_maps({{vol.get(), scene.T_world_cam}, {vol.get(), far}}, {}, c);
  EXPECT_TRUE(m.grid.empty());
  EXPECT_NE(m.grid_error.find("exceeds the budget"), std::string::npos) << m.grid_error;
  EXPECT_TRUE(m.octomap_bt.empty());
  // Small budgets.
  c.max_cells = 10;
  c.octomap = true;
  c.max_octree_nodes = 100;
  m = build_nav_maps({{vol.get(), scene.T_world_cam}}, {}, c);
  EXPECT_TRUE(m.grid.empty());
  EXPECT_FALSE(m.grid_error.empty());
  EXPECT_TRUE(m.octomap_bt.empty());
  EXPECT_NE(m.octomap_error.find("budget"), std::string::npos);
  // Beyond OctoMap's key range (+-1638 m at 5 cm): counted, not inserted.
  const OctomapResult o = build_octomap({{vol.get(), far}}, z_up());
  EXPECT_GT(o.voxels_out_of_range, 0u);
  EXPECT_TRUE(o.bt.empty());
}

TEST(NavMapBadInput, BadConfigThrows) {
  const SubmapViews none;
  auto bad = [&](auto&& edit) {
    NavMapConfig c;
    edit(c);
    EXPECT_THROW(build_nav_maps(none, {}, c), ConfigError);
  };
  bad([](NavMapConfig& c) { c.resolution = 0; });
  bad([](NavMapConfig& c) { c.resolution = std::nan(""); });
  bad([](NavMapConfig& c) { c.band_min = 2.0; });
  bad([](NavMapConfig& c) { c.up = Eigen::Vector3d::Zero(); });
  bad([](NavMapConfig& c) { c.floor_height = std::numeric_limits<double>::infinity(); });
  bad([](NavMapConfig& c) { c.min_occupied_voxels = 0; });
  bad([](NavMapConfig& c) { c.log_odds_free = 0.5f; });
  bad([](NavMapConfig& c) { c.octomap_resolution = -1; });
  bad([](NavMapConfig& c) { c.max_cells = 0; });
  EXPECT_THROW(build_occupancy_grid(none, Eigen::Vector3d(0, 0, std::nan("")), 0.0, NavMapConfig{}), ConfigError);
}
