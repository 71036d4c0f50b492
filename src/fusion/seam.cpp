#include "fusion/seam.h"

#include <map>
#include <set>

#include "slam/match/projection_search.h"

namespace cslam {

namespace {

std::vector<KeyFrame*> neighbourhood(KeyFrame& kf, int n) {
  std::vector<KeyFrame*> out = kf.best_covisibles(std::size_t(n));
  out.push_back(&kf);
  return out;
}

std::vector<MapPointPtr> points_of(const std::vector<KeyFrame*>& kfs) {
  std::vector<MapPointPtr> out;
  std::set<MapPoint*> seen;
  for (KeyFrame* kf : kfs)
    for (const auto& mp : kf->map_points)
      if (mp && !mp->bad && seen.insert(mp.get()).second) out.push_back(mp);
  return out;
}

}  // namespace

std::vector<SeamLink> match_seam(KeyFrame& kept_kf, KeyFrame& moved_kf, const SeamConfig& config) {
  const auto kept_side = neighbourhood(kept_kf, config.neighbours);
  const auto moved_side = neighbourhood(moved_kf, config.neighbours);
  // Votes for (moved point -> kept point) from both projection directions.
  std::map<std::pair<MapPointId, MapPointId>, int> votes;
  std::map<MapPointId, MapPointPtr> owner;
  auto vote = [&](const MapPointPtr& moved, const MapPointPtr& kept) {
    if (!moved || !kept || moved->bad || kept->bad) return;
    owner[moved->id] = moved;
    owner[kept->id] = kept;
    ++votes[{moved->id, kept->id}];
  };
  for (const auto& mp : points_of(moved_side))
    for (KeyFrame* k : kept_side) {
      const int idx = match_point_in_keyframe(*mp, *k, config.radius);
      if (idx >= 0) vote(mp, k->map_points[idx]);
    }
  for (const auto& mp : points_of(kept_side))
    for (KeyFrame* m : moved_side) {
      const int idx = match_point_in_keyframe(*mp, *m, config.radius);
      if (idx >= 0) vote(m->map_points[idx], mp);
    }
  // One partner per point: strongest votes first.
  std::vector<std::pair<int, std::pair<MapPointId, MapPointId>>> ranked;
  for (const auto& [pair, n] : votes) ranked.push_back({n, pair});
  std::stable_sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::set<MapPoint*> used;
  std::vector<SeamLink> pairs;
  for (const auto& [n, pair] : ranked) {
    const MapPointPtr& moved = owner[pair.first];
    const MapPointPtr& kept = owner[pair.second];
    if (used.count(moved.get()) || used.count(kept.get())) continue;
    used.insert(moved.get());
    used.insert(kept.get());
    pairs.push_back({kept, moved});
  }
  return pairs;
}

Seam link_seam(Map& kept_map, Map& moved_map, const std::vector<SeamLink>& pairs, const SeamConfig& config) {
  Seam seam;
  std::map<std::pair<KeyFrameId, KeyFrameId>, int> weight;
  for (const SeamLink& l : pairs) {
    if (l.kept->bad || l.moved->bad) continue;
    seam.points.push_back(l);
    l.moved->position = l.kept->position;
    moved_map.update_map_point(l.moved.get());
    for (const auto& [a, ia] : l.kept->observations)
      for (const auto& [b, ib] : l.moved->observations) ++weight[{a->id, b->id}];
  }
  for (const auto& [pair, w] : weight) {
    if (w < config.min_edge_weight) continue;
    KeyFramePtr a = kept_map.keyframe(pair.first), b = moved_map.keyframe(pair.second);
    if (a && b && !a->bad && !b->bad) seam.edges.push_back({a, b, w});
  }
  return seam;
}

Seam connect_seam(Map& kept_map, KeyFrame& kept_kf, Map& moved_map, KeyFrame& moved_kf, const SeamConfig& config) {
  return link_seam(kept_map, moved_map, match_seam(kept_kf, moved_kf, config), config);
}

}  // namespace cslam
