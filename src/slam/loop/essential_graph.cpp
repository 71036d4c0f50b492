#include "slam/loop/essential_graph.h"

namespace cslam {

namespace {
Sim3 to_sim3_world_cam(const SE3& T_cam_world) { return Sim3(T_cam_world.inverse()); }
}  // namespace

EssentialGraph build_essential_graph(const Map& map, const EssentialGraphInput& in) {
  EssentialGraph g;
  for (const auto& kf : map.keyframes()) {
    if (kf->bad) continue;
    g.index[kf.get()] = int(g.keyframes.size());
    g.keyframes.push_back(kf.get());
    auto it = in.initial_T_cam_world.find(kf.get());
    PoseGraphNode n;
    n.S_world_node = to_sim3_world_cam(it != in.initial_T_cam_world.end() ? it->second : kf->T_cam_world);
    n.fixed = in.fixed.count(kf.get()) > 0 || kf == map.origin();
    g.nodes.push_back(n);
  }
  auto measured = [&](KeyFrame* kf) {
    auto it = in.measured_T_cam_world.find(kf);
    return to_sim3_world_cam(it != in.measured_T_cam_world.end() ? it->second : kf->T_cam_world);
  };
  auto initial = [&](KeyFrame* kf) { return g.nodes[g.index.at(kf)].S_world_node; };
  std::set<std::pair<int, int>> added;
  auto add = [&](KeyFrame* a, KeyFrame* b, const Sim3& S_wa, const Sim3& S_wb, int& counter) {
    auto ia = g.index.find(a), ib = g.index.find(b);
    if (ia == g.index.end() || ib == g.index.end() || a == b) return;
    const auto key = std::minmax(ia->second, ib->second);
    if (!added.insert(key).second) return;
    g.edges.push_back({ia->second, ib->second, S_wa.inverse() * S_wb, 1.0});
    ++counter;
  };
  // New loop connections first: they carry the correction.
  for (const auto& [kf, links] : in.new_connections)
    for (KeyFrame* other : links) add(kf, other, initial(kf), initial(other), g.new_loop_edges);
  for (KeyFrame* kf : g.keyframes) {
    if (kf->parent && !kf->parent->bad)
      add(kf, kf->parent.get(), measured(kf), measured(kf->parent.get()), g.spanning_edges);
    // Not yet connected by local mapping: tied to the keyframe it was tracked against.
    if (kf->awaiting_connection() && !kf->creation_reference->bad)
      add(kf, kf->creation_reference.get(), Sim3(kf->T_cam_creation_ref).inverse(), Sim3(), g.spanning_edges);
    for (KeyFrame* l : kf->loop_edges) add(kf, l, measured(kf), measured(l), g.loop_edges);
    for (KeyFrame* c : kf->covisibles_with_weight(in.min_covisibility_weight))
      add(kf, c, measured(kf), measured(c), g.covisibility_edges);
  }
  return g;
}

}  // namespace cslam
