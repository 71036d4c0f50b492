#include "slam/loop/global_ba.h"

#include <algorithm>
#include <map>
#include <shared_mutex>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

namespace cslam {

void GlobalBa::snapshot(const std::vector<Map*>& maps,
                        const std::vector<std::pair<MapPointPtr, MapPointPtr>>& same_points) {
  if (maps.empty()) throw std::invalid_argument("GlobalBa::snapshot needs at least one map");
  maps_ = maps;
  change_index_.clear();
  problem_ = {};
  cameras_.clear();
  camera_map_.clear();
  map_points_.assign(maps.size(), {});
  // Each keyframe's camera: looked up for every observation of every point (hundreds of
  // thousands in a fused group), so hashed by address.
  std::unordered_map<const KeyFrame*, int> index;
  for (std::size_t m = 0; m < maps_.size(); ++m) {
    Map* map = maps_[m];
    change_index_.push_back(map->big_change_index());
    for (const auto& kf : map->keyframes()) {
      if (kf->bad) continue;
      index[kf.get()] = int(cameras_.size());
      cameras_.push_back(kf);
      camera_map_.push_back(m);
      const auto& c = kf->data->camera;
      problem_.cameras.push_back(
          {kf->T_cam_world, {c.fx, c.fy, c.cx, c.cy, kf->data->rgbd.bf}, map == maps_.front() && kf == map->origin()});
    }
  }
  // Variable of each point: seam pairs share the first point's variable.
  std::unordered_map<const MapPoint*, const MapPoint*> alias;
  for (const auto& [a, b] : same_points)
    if (a && b && !a->bad && !b->bad && a != b) alias.emplace(b.get(), a.get());
  std::unordered_map<const MapPoint*, int> variable;
  auto variable_of = [&](const MapPointPtr& mp, std::size_t m) {
    auto al = alias.find(mp.get());
    const MapPoint* key = al == alias.end() ? mp.get() : al->second;
    auto [it, inserted] = variable.emplace(key, int(problem_.points.size()));
    if (inserted) problem_.points.push_back(mp->position);
    map_points_[m].emplace_back(it->second, mp);
    return it->second;
  };
  struct Seen {
    const KeyFrame* kf;
    int camera, keypoint;
  };
  std::vector<Seen> seen;  // a point's observations by keyframes in the problem, in their order
  for (std::size_t m = 0; m < maps_.size(); ++m)
    maps_[m]->for_each_map_point_ptr([&](const MapPointPtr& mp) {
      if (mp->bad) return;
      seen.clear();
      for (const auto& [kf, idx] : mp->observations)
        if (const auto it = index.find(kf); it != index.end()) seen.push_back({kf, it->second, idx});
      if (seen.empty()) return;
      const int p = variable_of(mp, m);
      for (const Seen& s : seen) {
        const FrameData& f = *s.kf->data;
        BaObservation o;
        o.camera = s.camera;
        o.point = p;
        o.uv = f.features.undistorted[s.keypoint];
        o.u_right = f.u_right[s.keypoint];
        o.inv_sigma2 = f.pyramid->inv_sigma2[f.features.keypoints[s.keypoint].octave];
        problem_.observations.push_back(o);
      }
    });
}

BaResult GlobalBa::solve(int iterations, const std::atomic<bool>* abort, bool keep_progress) const {
  BaConfig cfg;
  cfg.keep_progress_on_abort = keep_progress;
  cfg.first_iterations = iterations;
  cfg.second_iterations = 0;
  return bundle_adjust(problem_, cfg, abort);
}

bool GlobalBa::usable(const BaResult& r) const {
  return (!r.aborted || r.partial) && r.T_cam_world.size() == cameras_.size();
}

bool GlobalBa::apply(const BaResult& r) {
  if (!usable(r)) return false;
  for (size_t m = 0; m < maps_.size(); ++m)
    if (maps_[m]->big_change_index() != change_index_[m]) return false;
  for (size_t m = 0; m < maps_.size(); ++m) apply_map(m, r);
  return true;
}

bool GlobalBa::apply_map(std::size_t m, const BaResult& r) {
  if (!usable(r) || maps_[m]->big_change_index() != change_index_[m]) return false;
  Map* map = maps_[m];
  // Optimised keyframes, and their poses before.
  std::map<KeyFrame*, SE3, ById> old_pose;
  for (size_t c = 0; c < cameras_.size(); ++c) {
    if (camera_map_[c] != m || cameras_[c]->bad) continue;
    old_pose[cameras_[c].get()] = cameras_[c]->T_cam_world;
    cameras_[c]->T_cam_world = r.T_cam_world[c];
  }
  for (const auto& [p, mp] : map_points_[m])
    if (!mp->bad) mp->position = r.points[p];
  // Keyframes created meanwhile keep their pose relative to the nearest optimised anchor, and the
  // points they reference that were not optimised follow them.
  const std::map<KeyFrame*, SE3, ById> moved_old_pose = carry_new_keyframes(*map, old_pose);
  if (!moved_old_pose.empty()) move_followers(m, moved_old_pose);
  // Every point's normal and distance bounds (this hold is the one tracking waits on: no copies).
  map->for_each_map_point([&](MapPoint& mp) { map->update_map_point(&mp); });
  map->note_big_change();  // tracking re-derives its last pose from its reference keyframe
  return true;
}

void GlobalBa::move_followers(std::size_t m, const std::map<KeyFrame*, SE3, ById>& moved_old_pose) {
  // The few points referenced by a carried keyframe, less those the BA optimised (found by a
  // binary search each, instead of indexing every optimised point).
  std::vector<MapPoint*> followers;
  maps_[m]->for_each_map_point([&](MapPoint& mp) {
    if (moved_old_pose.count(mp.reference)) followers.push_back(&mp);
  });
  std::sort(followers.begin(), followers.end());
  std::vector<char> optimised(followers.size(), 0);
  for (const auto& [p, mp] : map_points_[m]) {
    const auto it = std::lower_bound(followers.begin(), followers.end(), mp.get());
    if (it != followers.end() && *it == mp.get()) optimised[std::size_t(it - followers.begin())] = 1;
  }
  for (std::size_t i = 0; i < followers.size(); ++i) {
    if (optimised[i]) continue;
    MapPoint& mp = *followers[i];
    mp.position = mp.reference->T_world_cam() * (moved_old_pose.at(mp.reference) * mp.position);
  }
}

std::map<KeyFrame*, SE3, ById> carry_new_keyframes(const Map& map, const std::map<KeyFrame*, SE3, ById>& old_pose,
                                                   const std::unordered_set<const KeyFrame*>& known) {
  std::map<KeyFrame*, SE3, ById> carried;
  for (const auto& kf : map.keyframes()) {
    if (old_pose.count(kf.get()) || known.count(kf.get())) continue;
    KeyFrame* anc = kf->anchor();
    while (anc && !old_pose.count(anc)) anc = anc->anchor();
    if (!anc) continue;
    const SE3 T_kf_anc = kf->T_cam_world * old_pose.at(anc).inverse();
    carried[kf.get()] = kf->T_cam_world;
    kf->T_cam_world = T_kf_anc * anc->T_cam_world;
  }
  return carried;
}

void points_follow_references(Map& map, const std::map<KeyFrame*, SE3, ById>& old_pose,
                              const std::unordered_set<MapPoint*>& skip) {
  map.for_each_map_point([&](MapPoint& mp) {
    if (!mp.reference || skip.count(&mp)) return;
    const auto it = old_pose.find(mp.reference);
    if (it == old_pose.end()) return;
    mp.position = mp.reference->T_world_cam() * (it->second * mp.position);
  });
  map.for_each_map_point([&](MapPoint& mp) { map.update_map_point(&mp); });
}

bool run_global_ba_once(Map& map, int iterations) {
  GlobalBa gba;
  {
    std::shared_lock<std::shared_mutex> lock(map.mutex);
    if (map.num_keyframes() < 3) return false;
    gba.snapshot({&map});
  }
  const BaResult r = gba.solve(iterations, nullptr);
  std::unique_lock<std::shared_mutex> lock(map.mutex);
  return gba.apply(r);
}

}  // namespace cslam
