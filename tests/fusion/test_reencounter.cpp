// Re-encounters inside a fused group (fusion/reencounter.h): the correction of a query map that
// drifted from the group since the maps last met.
#include <algorithm>
#include <map>
#include <set>

#include <gtest/gtest.h>

#include "common/map_checks.h"
#include "fusion/fusion_manager.h"
#include "fusion/reencounter.h"
#include "two_maps_fixture.h"

using namespace cslam;

namespace {

// Keyframes of a map in creation order [lock held].
std::vector<KeyFramePtr> in_order(const Map& map) {
  std::vector<KeyFramePtr> out;
  for (const auto& kf : map.keyframes())
    if (!kf->bad) out.push_back(kf);
  std::sort(out.begin(), out.end(), [](const KeyFramePtr& a, const KeyFramePtr& b) { return a->id.seq < b->id.seq; });
  return out;
}

double mean_translation_gap(const std::vector<KeyFramePtr>& kfs, const std::map<const KeyFrame*, SE3>& reference) {
  double sum = 0;
  for (const auto& kf : kfs)
    sum += (kf->T_world_cam().translation() - reference.at(kf.get()).inverse().translation()).norm();
  return sum / double(kfs.size());
}

// One robot of the small synthetic scene over 240 frames, mapped offline (~40 keyframes).
test::ClientMap build_long_map(const test::TempDir& dir) {
  const auto r = test::render_test_scene(dir / "scene", "--frames 240 --seed 5");
  if (r.status != 0) throw std::runtime_error("cslam-synth failed: " + r.output);
  auto voc = std::make_shared<const Vocabulary>(Vocabulary::load(default_vocabulary_path()));
  return test::build_client_map(dir / "scene/robot_1", 1, voc);
}

}  // namespace

// A map, aligned with map a by ground truth, then drifts: its keyframes after the first few move
// by an error that grows with their order (to 1.5 deg / 6 cm at the last one), their points with
// them. The last keyframe re-encounters the group, measured at its pose before the drift. The
// correction puts that keyframe and its neighbourhood there, leaves the anchored keyframes (the
// observers of points linked by the earlier seam: here the first ones) where they were, and the
// essential graph takes the rest most of the way back.
TEST(Reencounter, DriftSinceTheLastSeamIsCorrectedBetweenTheAnchorsAndTheQuery) {
  test::TempDir dir("cslam_reencounter");
  const test::ClientMap b = build_long_map(dir);
  std::unique_lock<std::shared_mutex> lock(b.map->mutex);
  const std::vector<KeyFramePtr> kfs = in_order(*b.map);
  ASSERT_GE(kfs.size(), 20u);
  std::map<const KeyFrame*, SE3> true_pose;  // before the drift
  for (const auto& kf : kfs) true_pose[kf.get()] = kf->T_cam_world;
  {
    // Without drift the measured pose is the current one, and nothing moves.
    const ReencounterCorrection none = correct_reencounter(*b.map, *kfs.back(), kfs.back()->T_cam_world, {}, {});
    EXPECT_LT(none.T_correction.translation().norm(), 1e-12);
    for (const auto& kf : kfs) {
      EXPECT_LT((kf->T_cam_world.translation() - true_pose[kf.get()].translation()).norm(), 1e-9);
      EXPECT_LT(kf->T_cam_world.rotation().angularDistance(true_pose[kf.get()].rotation()), 1e-9);
    }
  }
  {
    // A drift that moves the query's image by less than a pixel is below what its features
    // measure: reported, nothing moved. Measured from the same keyframe 1.5 px off, it is corrected.
    const KeyFrame& q = *kfs.back();
    const double fx = q.data->camera.fx, depth = q.scene_median_depth();
    ASSERT_GT(depth, 0.1);
    auto off_by = [&](double px) {  // the measured pose: the query's camera moved sideways by px pixels
      return SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(px * depth / fx, 0, 0)) * q.T_cam_world;
    };
    const SE3 measured = off_by(0.6);
    const ReencounterCorrection small = correct_reencounter(*b.map, *kfs.back(), measured, {}, {});
    EXPECT_TRUE(small.skipped);
    EXPECT_NEAR(small.correction_px, 0.6, 1e-6);
    EXPECT_EQ(small.rigid, 0);
    for (const auto& kf : kfs)
      EXPECT_LT((kf->T_cam_world.translation() - true_pose[kf.get()].translation()).norm(), 1e-12);
    ReencounterConfig always;
    always.min_correction_px = 0;
    const ReencounterCorrection forced = correct_reencounter(*b.map, *kfs.back(), measured, {}, always);
    EXPECT_FALSE(forced.skipped);
    EXPECT_GT(forced.rigid, 0);
    EXPECT_LT((kfs.back()->T_cam_world.translation() - measured.translation()).norm(), 1e-9);
    // Back to where it was, then 1.5 px: corrected with the default.
    correct_reencounter(*b.map, *kfs.back(), true_pose.at(kfs.back().get()), {}, always);
    const ReencounterCorrection big = correct_reencounter(*b.map, *kfs.back(), off_by(1.5), {}, {});
    EXPECT_FALSE(big.skipped);
    EXPECT_NEAR(big.correction_px, 1.5, 1e-6);
    correct_reencounter(*b.map, *kfs.back(), true_pose.at(kfs.back().get()), {}, always);
    for (const auto& kf : kfs) true_pose[kf.get()] = kf->T_cam_world;  // what the rest of the test starts from
  }

  // The anchors: points of the first 4 keyframes. The drift starts after them.
  std::vector<MapPointPtr> anchors;
  for (std::size_t i = 0; i < 4; ++i)
    for (const auto& mp : kfs[i]->map_points)
      if (mp && !mp->bad) anchors.push_back(mp);
  Eigen::Matrix<double, 6, 1> xi;
  xi << 0.05, -0.03, 0.02, 0.2 * M_PI / 180, 1.4 * M_PI / 180, 0.4 * M_PI / 180;  // [rho, phi]
  std::map<const MapPoint*, bool> moved;
  std::set<const KeyFrame*> anchored;
  for (const auto& mp : anchors)
    for (const auto& [observer, idx] : mp->observations) anchored.insert(observer);
  const std::size_t n = kfs.size();
  for (std::size_t i = 0; i < n; ++i) {
    if (anchored.count(kfs[i].get())) continue;
    const double a = double(i) / double(n - 1);
    const SE3 T_err = SE3::exp_small(a * xi);  // applied on the world side
    const SE3 T_old_world_cam = kfs[i]->T_world_cam();
    kfs[i]->T_cam_world = (T_err * T_old_world_cam).inverse();
    for (const auto& mp : kfs[i]->map_points)
      if (mp && !mp->bad && mp->reference == kfs[i].get() && !moved[mp.get()]) {
        mp->position = T_err * mp->position;
        moved[mp.get()] = true;
      }
  }
  const KeyFramePtr query = kfs.back();
  std::vector<KeyFramePtr> drifting;
  for (const auto& kf : kfs)
    if (!anchored.count(kf.get())) drifting.push_back(kf);
  const double drifted_gap = mean_translation_gap(drifting, true_pose);

  std::map<const KeyFrame*, SE3> anchor_pose;
  for (const KeyFrame* k : anchored) anchor_pose[k] = k->T_cam_world;
  const ReencounterCorrection c = correct_reencounter(*b.map, *query, true_pose.at(query.get()), anchors, {});
  const double corrected_gap = mean_translation_gap(drifting, true_pose);
  std::printf("drift: mean keyframe gap %.4f m before the correction, %.4f m after (%d rigid, %d anchored, %d edges)\n",
              drifted_gap, corrected_gap, c.rigid, c.anchors, c.graph_edges);
  EXPECT_TRUE(c.pose_graph_converged);
  EXPECT_EQ(std::size_t(c.anchors), anchored.size());
  EXPECT_NEAR(c.T_correction.translation().norm(), xi.head<3>().norm(), 0.02);
  // The query keyframe sits at the measured pose; anchored keyframes did not move.
  EXPECT_LT((query->T_cam_world.translation() - true_pose.at(query.get()).translation()).norm(), 1e-9);
  for (const auto& [k, T] : anchor_pose) EXPECT_LT((k->T_cam_world.translation() - T.translation()).norm(), 1e-9);
  EXPECT_LT(corrected_gap, 0.3 * drifted_gap);
  test::expect_consistent(*b.map);
}

// A loop closure moves one map of a fused group alone; the group's links are balanced again by a
// group BA at that map's next keyframe (and only then).
TEST(Reencounter, LoopClosureInAFusedMapRebalancesTheGroup) {
  test::TempDir dir("cslam_reencounter_loop");
  test::TwoMaps m = test::build_two_maps(dir);
  FusionConfig cfg;
  cfg.threaded = false;             // the group BA runs inside notify()
  cfg.reencounter.enabled = false;  // only the loop closure may start it
  FusionManager fusion(cfg, std::make_shared<const Vocabulary>(Vocabulary::load(default_vocabulary_path())));
  fusion.restore_group(1, m.a.map, GroupId::from_value(7));
  fusion.restore_group(2, m.b.map, GroupId::from_value(7));
  KeyFramePtr kf;
  {
    std::shared_lock<std::shared_mutex> lock(m.a.map->mutex);
    for (const auto& k : in_order(*m.a.map))
      if (!k->covisibles().empty()) kf = k;
  }
  ASSERT_TRUE(kf);
  fusion.notify(1, m.a.map, kf);
  EXPECT_EQ(fusion.group_ba_stats().started, 0) << "no loop closed: nothing to balance";
  {
    std::unique_lock<std::shared_mutex> lock(m.a.map->mutex);
    m.a.map->note_loop_closed();
  }
  fusion.notify(1, m.a.map, kf);
  EXPECT_EQ(fusion.group_ba_stats().completed, 1);
  fusion.notify(1, m.a.map, kf);
  EXPECT_EQ(fusion.group_ba_stats().started, 1) << "the same loop is balanced once";
  fusion.finish();
}

namespace {

// Drifts every keyframe of `kfs` after the first `still` by an error growing with its order (on
// the world side), its reference points with it [unique lock held].
void drift(const std::vector<KeyFramePtr>& kfs, std::size_t still) {
  Eigen::Matrix<double, 6, 1> xi;
  xi << 0.04, -0.02, 0.02, 0.3 * M_PI / 180, 1.0 * M_PI / 180, 0.2 * M_PI / 180;  // [rho, phi]
  const std::size_t n = kfs.size();
  for (std::size_t i = still; i < n; ++i) {
    const SE3 T_err = SE3::exp_small(double(i) / double(n - 1) * xi);
    kfs[i]->T_cam_world = (T_err * kfs[i]->T_world_cam()).inverse();
    for (const auto& mp : kfs[i]->map_points)
      if (mp && !mp->bad && mp->reference == kfs[i].get()) mp->position = T_err * mp->position;
  }
}

}  // namespace

// The fusion thread plans and solves a re-encounter under shared locks and writes it under the
// unique one. A keyframe tracking created in between (not in the plan) keeps its pose relative to
// the keyframe it was tracked against; a big change in between (a loop correction) drops the
// plan, and nothing is written.
TEST(Reencounter, APlanAppliedLaterCarriesNewKeyframesAndYieldsToABigChange) {
  test::TempDir dir("cslam_reencounter_plan");
  const test::ClientMap b = build_long_map(dir);
  std::unique_lock<std::shared_mutex> lock(b.map->mutex);
  const std::vector<KeyFramePtr> kfs = in_order(*b.map);
  ASSERT_GE(kfs.size(), 20u);
  const KeyFramePtr query = kfs.back();
  const SE3 T_measured = query->T_cam_world;
  drift(kfs, 4);
  std::vector<MapPointPtr> anchors;
  for (std::size_t i = 0; i < 4; ++i)
    for (const auto& mp : kfs[i]->map_points)
      if (mp && !mp->bad) anchors.push_back(mp);

  // A big change between planning and applying: nothing is written.
  {
    ReencounterPlan plan = plan_reencounter(*b.map, *query, T_measured, anchors, {});
    solve_reencounter(plan, {});
    b.map->note_big_change();
    const SE3 before = query->T_cam_world;
    EXPECT_FALSE(apply_reencounter(*b.map, plan));
    EXPECT_EQ(query->T_cam_world.translation(), before.translation());
  }

  ReencounterPlan plan = plan_reencounter(*b.map, *query, T_measured, anchors, {});
  solve_reencounter(plan, {});
  ASSERT_TRUE(plan.result.converged);
  // Tracking inserts a keyframe 5 cm ahead of the query meanwhile, and one more on top of it.
  const SE3 T_new_query = SE3(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, -0.05));
  auto fresh = std::make_shared<KeyFrame>(b.map->ids().next_keyframe(), query->data, T_new_query * query->T_cam_world);
  fresh->creation_reference = query;
  fresh->T_cam_creation_ref = T_new_query;
  b.map->add_keyframe(fresh);
  auto fresher =
      std::make_shared<KeyFrame>(b.map->ids().next_keyframe(), query->data, T_new_query * fresh->T_cam_world);
  fresher->creation_reference = fresh;
  fresher->T_cam_creation_ref = T_new_query;
  b.map->add_keyframe(fresher);
  ASSERT_TRUE(apply_reencounter(*b.map, plan));
  // The query sits at the measured pose; the new keyframes kept their poses relative to it.
  EXPECT_LT((query->T_cam_world.translation() - T_measured.translation()).norm(), 1e-9);
  const SE3 T_fresh_query = fresh->T_cam_world * query->T_world_cam();
  const SE3 T_fresher_query = fresher->T_cam_world * query->T_world_cam();
  EXPECT_LT((T_fresh_query.translation() - T_new_query.translation()).norm(), 1e-9);
  EXPECT_LT((T_fresher_query.translation() - (T_new_query * T_new_query).translation()).norm(), 1e-9);
  EXPECT_LT(T_fresh_query.rotation().angularDistance(Eigen::Quaterniond::Identity()), 1e-9);
}
