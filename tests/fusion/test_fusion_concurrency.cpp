// Forced concurrency: a fusion (moving a map, linking the seam, group BA over both maps) running
// while the other client's loop closing corrects its map and runs its own global BA, and while
// tracking reads both maps. Nothing may deadlock, and both maps must stay consistent.
#include <atomic>
#include <thread>

#include <gtest/gtest.h>

#include "common/map_checks.h"
#include "fusion/fusion_manager.h"
#include "fusion/seam.h"
#include "slam/loop/global_ba.h"
#include "slam/loop/loop_closer.h"
#include "slam/map/map_locks.h"
#include "two_maps_fixture.h"

using namespace cslam;

TEST(FusionConcurrency, FusionDuringAnotherClientsLoopCorrectionKeepsBothMapsConsistent) {
  test::TempDir dir("cslam_fusion_concurrency");
  test::TwoMaps m = test::build_two_maps(dir);
  Map& a = *m.a.map;
  Map& b = *m.b.map;
  const SE3 T_a_b = m.a.T_gtworld_map.inverse() * m.b.T_gtworld_map;
  const SE3 nudge(Eigen::Quaterniond(Eigen::AngleAxisd(0.002, Eigen::Vector3d::UnitY())), Eigen::Vector3d(0.001, 0, 0));
  const int rounds = 12;
  std::atomic<int> fusions_applied{0}, loop_bas_applied{0}, corrections{0};
  std::atomic<bool> done{false};

  // Fusion thread: moves map b into a's frame, links the seam, runs the group BA (each round).
  std::thread fusion([&] {
    transform_map(b, T_a_b);
    for (int i = 0; i < rounds; ++i) {
      std::vector<std::pair<MapPointPtr, MapPointPtr>> links;
      {
        auto locks = lock_maps<std::unique_lock<std::shared_mutex>>({&a, &b});
        const auto ka = a.keyframes().back(), kb = b.keyframes().back();
        if (!ka->bad && !kb->bad)
          for (const auto& l : connect_seam(a, *ka, b, *kb).points) links.emplace_back(l.kept, l.moved);
      }
      GlobalBa gba;
      {
        auto locks = lock_maps<std::shared_lock<std::shared_mutex>>({&a, &b});
        gba.snapshot({&a, &b}, links);
      }
      const BaResult r = gba.solve(2, nullptr);
      {
        auto locks = lock_maps<std::unique_lock<std::shared_mutex>>({&a, &b});
        if (gba.apply(r)) ++fusions_applied;
      }
      transform_map(b, i % 2 ? nudge : nudge.inverse());  // re-fusion moves the map again
    }
  });
  // Client 1's loop closing: corrections (neighbourhood moved, big change) and its global BA.
  std::thread loop([&] {
    LoopClosingConfig lc;
    lc.global_ba_iterations = 2;
    LoopCloser closer(lc, m.a.map, false);
    for (int i = 0; i < rounds; ++i) {
      {
        std::unique_lock<std::shared_mutex> lock(a.mutex);
        auto kfs = a.keyframes();
        const SE3 delta(Eigen::Quaterniond(Eigen::AngleAxisd(0.001 * (i % 3 - 1), Eigen::Vector3d::UnitZ())),
                        Eigen::Vector3d::Zero());
        for (size_t k = kfs.size() / 2; k < kfs.size(); ++k) {
          kfs[k]->T_cam_world = kfs[k]->T_cam_world * delta;
          for (const auto& mp : kfs[k]->map_points)
            if (mp && mp->reference == kfs[k].get()) mp->position = delta.inverse() * mp->position;
        }
        a.note_big_change();
        ++corrections;
      }
      if (closer.run_global_ba()) ++loop_bas_applied;
    }
  });
  // Tracking of both clients: readers all along.
  std::thread tracking([&] {
    while (!done) {
      for (Map* map : {&a, &b}) {
        std::shared_lock<std::shared_mutex> lock(map->mutex);
        for (const auto& kf : map->keyframes()) ASSERT_TRUE(kf->T_cam_world.is_finite());
      }
    }
  });
  fusion.join();
  loop.join();
  done = true;
  tracking.join();

  EXPECT_EQ(corrections.load(), rounds);
  EXPECT_GT(fusions_applied.load() + loop_bas_applied.load(), 0);
  auto locks = lock_maps<std::shared_lock<std::shared_mutex>>({&a, &b});
  test::expect_consistent(a);
  test::expect_consistent(b);
}
