#include "fusion/reencounter.h"

#include <map>
#include <unordered_set>

#include "core/stopwatch.h"
#include "slam/loop/essential_graph.h"
#include "slam/loop/pose_graph.h"

namespace cslam {

ReencounterCorrection correct_reencounter(Map& query_map, KeyFrame& kf, const SE3& T_kf_world_measured,
                                          const std::vector<MapPointPtr>& anchor_points,
                                          const ReencounterConfig& config) {
  ReencounterCorrection out;
  const SE3 T_world_kf_old = kf.T_world_cam();
  out.T_correction = T_kf_world_measured.inverse() * kf.T_cam_world;
  // Rigid: the query keyframe, its covisible neighbourhood and the newest keyframes local mapping
  // has not connected yet (tracked against the neighbourhood), as in loop closing.
  std::vector<KeyFrame*> rigid = kf.covisibles();
  rigid.push_back(&kf);
  for (const auto& k : query_map.keyframes())
    if (!k->bad && k->awaiting_connection() && k.get() != &kf) rigid.push_back(k.get());
  EssentialGraphInput in;
  in.min_covisibility_weight = config.covisibility_edge_weight;
  std::map<KeyFrame*, SE3, ById> before;
  for (KeyFrame* n : rigid) {
    if (n->bad || before.count(n)) continue;
    before[n] = n->T_cam_world;
    in.initial_T_cam_world[n] = (n->T_cam_world * T_world_kf_old) * T_kf_world_measured;
    in.measured_T_cam_world[n] = n->T_cam_world;
    in.fixed.insert(n);
  }
  out.rigid = int(before.size());
  // Anchors: observers of points already linked to the group, unless they moved rigidly.
  for (const auto& mp : anchor_points) {
    if (!mp || mp->bad) continue;
    for (const auto& [observer, idx] : mp->observations)
      if (!observer->bad && !before.count(observer) && in.fixed.insert(observer).second) ++out.anchors;
  }
  // Points seen by the rigid set move with the first keyframe of the set that sees them.
  std::unordered_set<MapPoint*> moved;
  for (auto& [n, T_old] : before) {
    const SE3 delta = in.initial_T_cam_world[n].inverse() * T_old;  // T_world_new * T_old_world
    for (const auto& mp : n->map_points)
      if (mp && !mp->bad && moved.insert(mp.get()).second) mp->position = delta * mp->position;
    n->T_cam_world = in.initial_T_cam_world[n];
  }
  // The query map's essential graph between the rigid set and the anchors; points follow their
  // reference keyframes (those placed with the rigid set stay: the graph holds the set).
  Stopwatch sw;
  const EssentialGraph graph = build_essential_graph(query_map, in);
  out.graph_edges = int(graph.edges.size());
  PoseGraphConfig pgc;
  pgc.fix_scale = true;
  pgc.max_iterations = config.pose_graph_iterations;
  const PoseGraphResult r = optimize_pose_graph(graph.nodes, graph.edges, pgc);
  out.pose_graph_ms = sw.ms();
  out.pose_graph_converged = r.converged;
  if (r.converged) {
    std::map<KeyFrame*, SE3, ById> pre_opt;
    for (std::size_t i = 0; i < graph.keyframes.size(); ++i) {
      KeyFrame* k = graph.keyframes[i];
      pre_opt[k] = k->T_cam_world;
      k->T_cam_world = r.S_world_node[i].to_se3().inverse();
    }
    for (const auto& mp : query_map.map_points()) {
      if (moved.count(mp.get())) continue;  // placed with the rigid set, which the graph holds
      auto it = pre_opt.find(mp->reference);
      if (!mp->reference || it == pre_opt.end()) continue;
      mp->position = mp->reference->T_world_cam() * (it->second * mp->position);
    }
  }
  for (const auto& mp : query_map.map_points()) query_map.update_map_point(mp.get());
  query_map.note_big_change();
  return out;
}

}  // namespace cslam
