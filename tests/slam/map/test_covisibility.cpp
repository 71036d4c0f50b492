// Covisibility graph, spanning tree and observation bookkeeping, including after culling.
#include <gtest/gtest.h>

#include "common/fake_frame_data.h"
#include "slam/map/map.h"

using namespace cslam;

namespace {

using test::fake_frame_data;

struct Fixture {
  Fixture() : map(1, 0, std::make_shared<IdAllocator>(1)), pyramid(ScalePyramid::from(OrbExtractor())) {}
  KeyFramePtr add_keyframe() {
    auto kf = std::make_shared<KeyFrame>(map.ids().next_keyframe(), fake_frame_data(200, pyramid), SE3());
    map.add_keyframe(kf);
    return kf;
  }
  MapPointPtr add_point() {
    auto mp = std::make_shared<MapPoint>(map.ids().next_map_point(), Eigen::Vector3d(0, 0, 1), nullptr, cv::Vec3b());
    map.add_map_point(mp);
    return mp;
  }
  // Points [first, first+count) observed by every keyframe in kfs at the point's index.
  std::vector<MapPointPtr> share(const std::vector<KeyFramePtr>& kfs, int first, int count) {
    std::vector<MapPointPtr> out;
    for (int i = first; i < first + count; ++i) {
      auto mp = add_point();
      for (const auto& kf : kfs) Map::add_observation(kf.get(), i, mp);
      mp->reference = kfs.front().get();
      out.push_back(mp);
    }
    return out;
  }
  Map map;
  std::shared_ptr<const ScalePyramid> pyramid;
};

}  // namespace

TEST(Covisibility, WeightsThresholdAndSpanningTree) {
  Fixture fx;
  auto a = fx.add_keyframe(), b = fx.add_keyframe(), c = fx.add_keyframe();
  fx.share({a, b}, 0, 40);   // a-b: 40
  fx.share({b, c}, 40, 20);  // b-c: 20
  fx.share({a, c}, 60, 10);  // a-c: 10 (< 15: no edge while stronger ones exist)
  for (auto& kf : {a, b, c}) fx.map.update_connections(kf.get());
  EXPECT_EQ(a->weight(b.get()), 40);
  EXPECT_EQ(b->weight(a.get()), 40);
  EXPECT_EQ(b->weight(c.get()), 20);
  EXPECT_EQ(a->weight(c.get()), 0);
  ASSERT_EQ(b->ordered_connections.size(), 2u);
  EXPECT_EQ(b->ordered_connections.front().second, a.get());  // strongest first
  // Spanning tree: a is the origin; b's parent is its strongest neighbour a; c's is b.
  EXPECT_EQ(fx.map.origin(), a);
  EXPECT_EQ(b->parent, a);
  EXPECT_EQ(c->parent, b);
  EXPECT_TRUE(a->children.count(b.get()));
}

TEST(Covisibility, CullingKeyframeRepairsGraphTreeAndObservations) {
  Fixture fx;
  auto a = fx.add_keyframe(), b = fx.add_keyframe(), c = fx.add_keyframe(), d = fx.add_keyframe();
  fx.share({a, b}, 0, 50);
  fx.share({b, c}, 50, 50);
  fx.share({b, d}, 100, 30);
  fx.share({a, c, d}, 150, 20);  // c and d also see a: the tree can be repaired without b
  for (auto& kf : {a, b, c, d}) fx.map.update_connections(kf.get());
  ASSERT_EQ(c->parent, b);
  ASSERT_EQ(d->parent, b);
  const std::size_t points_before = fx.map.num_map_points();

  fx.map.set_keyframe_bad(b.get());

  EXPECT_TRUE(b->bad);
  EXPECT_EQ(fx.map.num_keyframes(), 3u);
  EXPECT_EQ(fx.map.keyframe(b->id), nullptr);
  // No keyframe still lists b as a neighbour.
  for (auto& kf : {a, c, d}) {
    EXPECT_EQ(kf->weight(b.get()), 0);
    for (const auto& [w, n] : kf->ordered_connections) EXPECT_NE(n, b.get());
  }
  // b's children were re-attached to keyframes still in the tree.
  EXPECT_NE(c->parent, nullptr);
  EXPECT_NE(c->parent.get(), b.get());
  EXPECT_NE(d->parent.get(), b.get());
  EXPECT_FALSE(a->children.count(b.get()));
  // Points that were seen only by b and one other keyframe lost their second RGB-D observation
  // (num_obs 4 -> 2) and were culled; points still seen twice survive.
  EXPECT_EQ(fx.map.num_map_points(), points_before - 130);
  for (const auto& mp : fx.map.map_points()) EXPECT_FALSE(mp->in_keyframe(b.get()));
  // b's pose relative to its parent is kept for trajectories that reference it.
  EXPECT_NE(b->parent, nullptr);
}

// The graph is updated one side at a time: a keyframe whose connections were recomputed without a
// neighbour leaves the neighbour's edge to it in place. Culling it must remove that edge too, or
// the neighbour would point at a freed keyframe once no frame refers to the culled one.
TEST(Covisibility, CullingRemovesEdgesTheCulledKeyframeNoLongerListed) {
  Fixture fx;
  auto a = fx.add_keyframe(), b = fx.add_keyframe(), c = fx.add_keyframe();
  fx.share({a, b}, 0, 40);
  const auto bc = fx.share({b, c}, 40, 40);
  for (auto& kf : {a, b, c}) fx.map.update_connections(kf.get());
  ASSERT_EQ(c->weight(b.get()), 40);
  for (const auto& mp : bc) fx.map.erase_observation(b.get(), mp);  // b stops seeing them
  fx.map.update_connections(b.get());
  ASSERT_EQ(b->weight(c.get()), 0);
  ASSERT_EQ(c->weight(b.get()), 40);  // c's side is stale until c is updated
  fx.map.set_keyframe_bad(b.get());
  EXPECT_EQ(c->weight(b.get()), 0);
  for (const auto& [w, kf] : c->ordered_connections) EXPECT_NE(kf, b.get());
  EXPECT_EQ(a->weight(b.get()), 0);
}

TEST(Covisibility, OriginIsNeverCulledAndLockedKeyframesAreDeferred) {
  Fixture fx;
  auto a = fx.add_keyframe(), b = fx.add_keyframe();
  fx.share({a, b}, 0, 30);
  fx.map.update_connections(b.get());
  fx.map.set_keyframe_bad(a.get());
  EXPECT_FALSE(a->bad);
  b->no_erase = 1;
  fx.map.set_keyframe_bad(b.get());
  EXPECT_FALSE(b->bad);
  EXPECT_TRUE(b->erase_requested);
}

TEST(MapPoints, ReplaceMovesObservationsAndFreesTheOldPoint) {
  Fixture fx;
  auto a = fx.add_keyframe(), b = fx.add_keyframe();
  auto p = fx.share({a}, 0, 1)[0];
  auto q = fx.share({b}, 1, 1)[0];
  std::weak_ptr<MapPoint> weak_q = q;
  fx.map.replace_map_point(q, p);
  EXPECT_TRUE(q->bad);
  EXPECT_EQ(q->replaced, p);
  EXPECT_TRUE(p->in_keyframe(b.get()));
  EXPECT_EQ(b->map_points[1], p);
  EXPECT_EQ(fx.map.num_map_points(), 1u);
  q.reset();
  EXPECT_TRUE(weak_q.expired());  // erased objects are really freed once unused
}

TEST(Covisibility, EveryChangeOfAKeyframesSlotsChangesItsVersion) {
  Fixture fx;
  auto a = fx.add_keyframe(), b = fx.add_keyframe(), c = fx.add_keyframe(), d = fx.add_keyframe();
  auto versions = [&] {
    std::vector<std::uint64_t> out;
    for (const auto& kf : {a, b, c, d}) out.push_back(kf->map_points.version());
    return out;
  };
  auto changed = [](const std::vector<std::uint64_t>& before, const std::vector<std::uint64_t>& after) {
    std::vector<bool> out;
    for (std::size_t k = 0; k < before.size(); ++k) out.push_back(after[k] != before[k]);
    return out;
  };
  auto v = versions();
  const auto abc = fx.share({a, b, c}, 50, 3);  // points at slots 50..52 of a, b and c (RGB-D: each seen twice)
  EXPECT_EQ(changed(v, versions()), (std::vector<bool>{true, true, true, false}));
  v = versions();
  fx.map.erase_observation(a.get(), abc[0]);  // b and c still see it: it stays good
  EXPECT_EQ(a->map_points[50], nullptr);
  EXPECT_FALSE(abc[0]->bad);
  EXPECT_EQ(changed(v, versions()), (std::vector<bool>{true, false, false, false}));
  v = versions();
  fx.map.set_map_point_bad(abc[1]);
  EXPECT_EQ(changed(v, versions()), (std::vector<bool>{true, true, true, false}));
  const auto in_d = fx.share({d}, 53, 1);
  v = versions();
  fx.map.replace_map_point(abc[2], in_d[0]);  // a, b and c now hold d's point at slot 52
  for (const auto& kf : {a, b, c}) EXPECT_EQ(kf->map_points[52], in_d[0]);
  EXPECT_EQ(changed(v, versions()), (std::vector<bool>{true, true, true, false}));
  // Reading changes nothing.
  v = versions();
  int held = 0;
  for (const auto& kf : {a, b, c, d})
    for (const auto& mp : kf->map_points) held += mp != nullptr;
  EXPECT_EQ(held, 6);  // the first point in b and c, d's point in all four
  EXPECT_EQ(changed(v, versions()), (std::vector<bool>{false, false, false, false}));
}
