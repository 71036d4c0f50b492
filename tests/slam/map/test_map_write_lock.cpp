// Whole-map readers yield to writers: MapWriteLock counts the writers waiting for a map's lock,
// the snapshot copy (export_map_state) gives the lock up when one waits and copies again after it,
// always in one uninterrupted shared-lock hold.
#include <gtest/gtest.h>

#include <atomic>
#include <functional>
#include <thread>
#include <unordered_set>

#include "common/fake_frame_data.h"
#include "slam/map/map_state.h"

using namespace cslam;

namespace {

using test::fake_frame_data;

constexpr int kPointsPerStep = 50;

// A map grown in steps: step k adds keyframe k with kPointsPerStep new points (keypoints
// 0..49) that it observes, and also observes the previous step's points (keypoints 50..99).
// After K steps: K keyframes, 50 K points, 50 K + 50 (K - 1) observations.
struct GrowingMap {
  GrowingMap() : map(1, 0, std::make_shared<IdAllocator>(1)), pyramid(ScalePyramid::from(OrbExtractor())) {}
  void step() {  // [unique]
    auto kf =
        std::make_shared<KeyFrame>(map.ids().next_keyframe(), fake_frame_data(2 * kPointsPerStep, pyramid), SE3());
    map.add_keyframe(kf);
    for (int i = 0; i < int(previous.size()); ++i) Map::add_observation(kf.get(), kPointsPerStep + i, previous[i]);
    std::vector<MapPointPtr> created;
    for (int i = 0; i < kPointsPerStep; ++i) {
      auto mp =
          std::make_shared<MapPoint>(map.ids().next_map_point(), Eigen::Vector3d(i, steps, 1), kf.get(), cv::Vec3b());
      Map::add_observation(kf.get(), i, mp);
      map.add_map_point(mp);
      created.push_back(mp);
    }
    map.update_connections(kf.get());
    previous = std::move(created);
    ++steps;
  }
  Map map;
  std::shared_ptr<const ScalePyramid> pyramid;
  std::vector<MapPointPtr> previous;
  int steps = 0;
};

// Joins in its destructor, so that a failed assertion cannot leave a joinable thread behind.
struct JoiningThread {
  explicit JoiningThread(std::function<void()> f) : t(std::move(f)) {}
  ~JoiningThread() {
    if (t.joinable()) t.join();
  }
  std::thread t;
};

void expect_same(const MapState& a, const MapState& b) {
  ASSERT_EQ(a.keyframes.size(), b.keyframes.size());
  for (std::size_t i = 0; i < a.keyframes.size(); ++i) {
    EXPECT_EQ(a.keyframes[i].id, b.keyframes[i].id);
    EXPECT_EQ(a.keyframes[i].parent, b.keyframes[i].parent);
    EXPECT_EQ(a.keyframes[i].connections, b.keyframes[i].connections);
    EXPECT_EQ(a.keyframes[i].data, b.keyframes[i].data);
  }
  ASSERT_EQ(a.points.size(), b.points.size());
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    EXPECT_EQ(a.points[i].id, b.points[i].id);
    EXPECT_EQ(a.points[i].position, b.points[i].position);
    EXPECT_EQ(a.points[i].observations, b.points[i].observations);
    EXPECT_EQ(a.points[i].reference, b.points[i].reference);
  }
  EXPECT_EQ(a.origin, b.origin);
}

// A copy of the map after exactly `steps` whole steps: the counts, and every observation naming a
// copied keyframe at the keypoint the step gave it.
void expect_whole_steps(const MapState& s) {
  const std::size_t k = s.keyframes.size();
  ASSERT_GT(k, 0u);
  EXPECT_EQ(s.points.size(), kPointsPerStep * k);
  std::unordered_set<KeyFrameId> ids;
  for (const auto& kf : s.keyframes) ids.insert(kf.id);
  std::size_t observations = 0;
  for (const auto& p : s.points) {
    for (const auto& [kf, idx] : p.observations) {
      EXPECT_TRUE(ids.count(kf));
      EXPECT_LT(idx, 2 * kPointsPerStep);
    }
    observations += p.observations.size();
  }
  EXPECT_EQ(observations, kPointsPerStep * k + kPointsPerStep * (k - 1));
}

}  // namespace

TEST(MapWriteLock, CountsWaitingWritersAndRecordsWaits) {
  GrowingMap g;
  EXPECT_EQ(g.map.writers_waiting(), 0);
  {
    MapWriteLock lock(g.map, /*record_wait=*/true);
    EXPECT_EQ(g.map.writers_waiting(), 0);  // holds it: no longer waiting
    g.step();
  }
  { MapWriteLock lock(g.map); }  // not recorded
  std::shared_lock<std::shared_mutex> lock(g.map.mutex);
  ASSERT_EQ(g.map.recorded_write_waits().size(), 1u);
  EXPECT_GE(g.map.recorded_write_waits()[0].ms, 0.0);
}

TEST(MapStateExport, AbandonsWhileAWriterWaitsAndCopiesOtherwise) {
  GrowingMap g;
  for (int i = 0; i < 12; ++i) g.step();  // 600 points: several checks during the copy
  MapState uninterrupted;
  {
    std::shared_lock<std::shared_mutex> lock(g.map.mutex);
    uninterrupted = export_map_state(g.map);
    MapState again;
    ASSERT_TRUE(export_map_state(g.map, again, /*yield_to_writers=*/true));  // nobody waits
    tidy_map_state(uninterrupted);
    tidy_map_state(again);
    expect_same(uninterrupted, again);
  }
  std::atomic<bool> written{false};
  std::unique_ptr<JoiningThread> writer;
  {
    std::shared_lock<std::shared_mutex> lock(g.map.mutex);
    writer = std::make_unique<JoiningThread>([&] {
      MapWriteLock w(g.map);  // waits for the shared lock above
      g.step();
      written = true;
    });
    while (g.map.writers_waiting() == 0) std::this_thread::yield();  // the writer has asked for the lock
    MapState partial;
    EXPECT_FALSE(export_map_state(g.map, partial, /*yield_to_writers=*/true));
    MapState forced;  // not yielding: copies regardless
    ASSERT_TRUE(export_map_state(g.map, forced, /*yield_to_writers=*/false));
    tidy_map_state(forced);
    expect_same(uninterrupted, forced);
    EXPECT_FALSE(written);
  }
  writer.reset();  // joins: the writer got the lock once it was released
  EXPECT_TRUE(written);
  EXPECT_EQ(g.map.writers_waiting(), 0);
  MapState after = export_map_state_yielding(g.map);
  EXPECT_EQ(after.export_yields, 0);
  EXPECT_FALSE(after.export_forced);
  tidy_map_state(after);
  EXPECT_EQ(after.keyframes.size(), 13u);
  expect_whole_steps(after);
}

TEST(MapStateExport, YieldingCopyLetsAWaitingWriterGoFirst) {
  GrowingMap g;
  for (int i = 0; i < 4; ++i) g.step();
  MapState copy;
  std::unique_ptr<JoiningThread> writer, exporter;
  {
    std::shared_lock<std::shared_mutex> lock(g.map.mutex);
    writer = std::make_unique<JoiningThread>([&] {
      MapWriteLock w(g.map);
      g.step();
    });
    while (g.map.writers_waiting() == 0) std::this_thread::yield();
    // Started while the writer waits: whether its shared lock is granted at once (a reader-
    // preferring lock) or only after the writer, it must not copy before the writer is through.
    exporter = std::make_unique<JoiningThread>([&] { copy = export_map_state_yielding(g.map); });
  }
  exporter.reset();
  writer.reset();
  EXPECT_LE(copy.export_yields, 1);
  EXPECT_FALSE(copy.export_forced);
  tidy_map_state(copy);
  EXPECT_EQ(copy.keyframes.size(), 5u);  // includes the writer's step
  expect_whole_steps(copy);
}

TEST(MapStateExport, ZeroYieldsAllowedCopiesWithoutYielding) {
  GrowingMap g;
  g.step();
  const MapState s = export_map_state_yielding(g.map, /*max_yields=*/0);
  EXPECT_EQ(s.export_yields, 0);
  EXPECT_TRUE(s.export_forced);
  EXPECT_EQ(s.points.size(), std::size_t(kPointsPerStep));
}

// A writer mutating the map under MapWriteLock while another thread exports again and again:
// every export completes, within the yield bound, and holds whole steps only.
TEST(MapStateExport, ConcurrentWriterAndExporterGiveConsistentCopies) {
  GrowingMap g;
  g.step();
  constexpr int kSteps = 200;
  std::atomic<bool> writer_done{false};
  std::vector<MapState> copies;
  {
    JoiningThread exporter([&] {
      auto copy = [&] {
        MapState s = export_map_state_yielding(g.map, 20);
        tidy_map_state(s);
        copies.push_back(std::move(s));
      };
      while (!writer_done) copy();
      copy();  // after the last step
    });
    JoiningThread writer([&] {
      for (int i = 0; i < kSteps; ++i) {
        MapWriteLock w(g.map, /*record_wait=*/true);
        g.step();
      }
      writer_done = true;
    });
  }
  ASSERT_FALSE(copies.empty());
  std::size_t last = 0;
  for (const MapState& s : copies) {
    expect_whole_steps(s);
    EXPECT_LE(s.export_yields, 20);
    EXPECT_GE(s.keyframes.size(), last);  // copies in order never go back
    last = s.keyframes.size();
  }
  EXPECT_EQ(copies.back().keyframes.size(), std::size_t(kSteps + 1));
  std::shared_lock<std::shared_mutex> lock(g.map.mutex);
  EXPECT_EQ(g.map.recorded_write_waits().size(), std::size_t(kSteps));
  EXPECT_EQ(g.map.writers_waiting(), 0);
}
