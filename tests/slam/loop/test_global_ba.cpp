// Global BA interrupted and restarted many times leaves the map consistent.
#include <thread>

#include <gtest/gtest.h>

#include "common/map_checks.h"
#include "common/run_program.h"
#include "geometry/camera_io.h"
#include "io/tum_dataset.h"
#include "slam/loop/loop_closer.h"
#include "slam/client_slam.h"

using namespace cslam;

using test::expect_consistent;

TEST(GlobalBa, InterruptedManyTimesLeavesMapConsistent) {
  test::TempDir dir("cslam_gba");
  const auto r = test::render_test_scene(dir / "scene", "--seed 9");
  ASSERT_EQ(r.status, 0) << r.output;
  const TumDataset ds = open_tum_dataset(dir / "scene/robot_1");
  ClientInfo info;
  info.id = 1;
  info.camera = load_camera_file(dir / "scene/robot_1/camera.yaml");
  SlamConfig cfg;
  cfg.threaded = false;
  cfg.loop.enabled = false;
  auto voc = std::make_shared<const Vocabulary>(Vocabulary::load(default_vocabulary_path()));
  ClientSlam slam(info, cfg, voc);
  for (const auto& p : ds.pairs) {
    const auto im = load_rgbd(p);
    RgbdFrame f;
    f.client = 1;
    f.timestamp = p.rgb_time;
    f.bgr = im.bgr;
    f.depth = im.depth;
    slam.process(f);
  }
  slam.finish();
  auto map = slam.maps().front();
  const auto before = slam.trajectory();

  LoopClosingConfig lc;
  lc.global_ba_iterations = 3;
  LoopCloser closer(lc, map, false);
  int applied = 0;
  for (int round = 0; round < 20; ++round) {
    // Another thread bumps the map (as a fusion or loop correction would) while the BA solves:
    // every such run must be discarded, never half-applied.
    std::thread bump;
    if (round % 2 == 0)
      bump = std::thread([&] {
        std::unique_lock<std::shared_mutex> lock(map->mutex);
        map->note_big_change();
      });
    if (closer.run_global_ba()) ++applied;
    if (bump.joinable()) bump.join();
    std::shared_lock<std::shared_mutex> lock(map->mutex);
    expect_consistent(*map);
  }
  EXPECT_GE(applied, 10);  // the undisturbed runs are applied
  const auto stats = closer.stats();
  EXPECT_EQ(stats.global_ba_started, 20);
  EXPECT_EQ(stats.global_ba_completed + stats.global_ba_discarded, 20);
  // The map is still a good map: the trajectory stays close to ground truth.
  const auto after = slam.trajectory();
  ASSERT_EQ(after.size(), before.size());
  for (size_t i = 0; i < after.size(); ++i)
    EXPECT_LT((after[i].T_world_cam.translation() - before[i].T_world_cam.translation()).norm(), 0.05);
}
