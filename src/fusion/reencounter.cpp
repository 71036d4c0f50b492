#include "fusion/reencounter.h"

#include <limits>
#include <unordered_set>

#include "core/stopwatch.h"
#include "slam/loop/global_ba.h"

namespace cslam {

ReencounterPlan plan_reencounter(const Map& query_map, const KeyFrame& kf, const SE3& T_kf_world_measured,
                                 const std::vector<MapPointPtr>& anchor_points, const ReencounterConfig& config) {
  ReencounterPlan plan;
  plan.change_index = query_map.big_change_index();
  plan.keyframes = query_map.keyframes();
  ReencounterCorrection& out = plan.summary;
  const SE3 T_world_kf_old = kf.T_world_cam();
  out.T_correction = T_kf_world_measured.inverse() * kf.T_cam_world;
  out.correction_px = correction_px(out.T_correction, kf.data->camera.fx, kf.scene_median_depth());
  if (out.correction_px < config.min_correction_px) {
    out.skipped = true;
    return plan;
  }
  // Rigid: the query keyframe, its covisible neighbourhood and the newest keyframes local mapping
  // has not connected yet (tracked against the neighbourhood), as in loop closing.
  std::vector<KeyFrame*> rigid = kf.covisibles();
  rigid.push_back(const_cast<KeyFrame*>(&kf));
  for (const auto& k : plan.keyframes)
    if (!k->bad && k->awaiting_connection() && k.get() != &kf) rigid.push_back(k.get());
  EssentialGraphInput in;
  in.min_covisibility_weight = config.covisibility_edge_weight;
  for (KeyFrame* n : rigid) {
    if (n->bad || plan.rigid_T_cam_world.count(n)) continue;
    const SE3 T_new = (n->T_cam_world * T_world_kf_old) * T_kf_world_measured;
    plan.rigid_T_cam_world[n] = T_new;
    in.initial_T_cam_world[n] = T_new;
    in.measured_T_cam_world[n] = n->T_cam_world;
    in.fixed.insert(n);
  }
  out.rigid = int(plan.rigid_T_cam_world.size());
  // Anchors: observers of points already linked to the group, unless they move rigidly.
  for (const auto& mp : anchor_points) {
    if (!mp || mp->bad) continue;
    for (const auto& [observer, idx] : mp->observations)
      if (!observer->bad && !plan.rigid_T_cam_world.count(observer) && in.fixed.insert(observer).second) ++out.anchors;
  }
  // The query map's essential graph between the rigid set and the anchors.
  plan.graph = build_essential_graph(query_map, in);
  out.graph_edges = int(plan.graph.edges.size());
  return plan;
}

double correction_px(const SE3& T_correction, double focal_px, double median_depth_m) {
  if (!(median_depth_m > 0)) return std::numeric_limits<double>::infinity();  // no scene seen: always correct
  const double angle = Eigen::AngleAxisd(T_correction.rotation()).angle();
  return focal_px * (T_correction.translation().norm() / median_depth_m + angle);
}

void solve_reencounter(ReencounterPlan& plan, const ReencounterConfig& config) {
  if (plan.summary.skipped) return;  // below what the features measure: nothing to solve
  Stopwatch sw;
  PoseGraphConfig pgc;
  pgc.fix_scale = true;
  pgc.max_iterations = config.pose_graph_iterations;
  plan.result = optimize_pose_graph(plan.graph.nodes, plan.graph.edges, pgc);
  plan.summary.pose_graph_ms = sw.ms();
  plan.summary.pose_graph_converged = plan.result.converged;
}

bool apply_reencounter(Map& query_map, ReencounterPlan& plan) {
  if (plan.summary.skipped) return true;  // below what the features measure: nothing to write
  if (query_map.big_change_index() != plan.change_index) return false;
  // The rigid set; points it sees move with the first keyframe of the set that sees them.
  std::map<KeyFrame*, SE3, ById> before;  // every keyframe this moves: its pose before
  std::unordered_set<MapPoint*> moved;
  for (auto& [n, T_new] : plan.rigid_T_cam_world) {
    if (n->bad) continue;
    before[n] = n->T_cam_world;
    const SE3 delta = T_new.inverse() * n->T_cam_world;  // T_world_new * T_old_world
    for (const auto& mp : n->map_points)
      if (mp && !mp->bad && moved.insert(mp.get()).second) mp->position = delta * mp->position;
    n->T_cam_world = T_new;
  }
  // The graph's result; points follow their reference keyframes (those placed with the rigid set
  // stay: the graph holds the set).
  std::map<KeyFrame*, SE3, ById> pre_opt;
  if (plan.result.converged) {
    for (std::size_t i = 0; i < plan.graph.keyframes.size(); ++i) {
      KeyFrame* k = plan.graph.keyframes[i];
      if (k->bad) continue;
      pre_opt[k] = k->T_cam_world;
      before.emplace(k, k->T_cam_world);
      k->T_cam_world = plan.result.S_world_node[i].to_se3().inverse();
    }
  }
  std::unordered_set<const KeyFrame*> planned;  // keyframes created since the plan are not in it
  for (const auto& k : plan.keyframes) planned.insert(k.get());
  for (const auto& [k, T_old] : carry_new_keyframes(query_map, before, planned)) pre_opt[k] = T_old;
  points_follow_references(query_map, pre_opt, moved);
  query_map.note_big_change();
  return true;
}

ReencounterCorrection correct_reencounter(Map& query_map, KeyFrame& kf, const SE3& T_kf_world_measured,
                                          const std::vector<MapPointPtr>& anchor_points,
                                          const ReencounterConfig& config) {
  ReencounterPlan plan = plan_reencounter(query_map, kf, T_kf_world_measured, anchor_points, config);
  solve_reencounter(plan, config);
  apply_reencounter(query_map, plan);
  return plan.summary;
}

}  // namespace cslam
