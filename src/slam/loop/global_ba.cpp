#include "slam/loop/global_ba.h"

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
  points_.clear();
  std::map<KeyFrame*, int, ById> index;
  for (Map* map : maps_) {
    change_index_.push_back(map->big_change_index());
    for (const auto& kf : map->keyframes()) {
      if (kf->bad) continue;
      index[kf.get()] = int(cameras_.size());
      cameras_.push_back(kf);
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
  auto variable_of = [&](const MapPointPtr& mp) {
    auto al = alias.find(mp.get());
    const MapPoint* key = al == alias.end() ? mp.get() : al->second;
    auto [it, inserted] = variable.emplace(key, int(points_.size()));
    if (inserted) {
      points_.emplace_back();
      problem_.points.push_back(mp->position);
    }
    points_[it->second].push_back(mp);
    return it->second;
  };
  for (Map* map : maps_)
    for (const auto& mp : map->map_points()) {
      if (mp->bad) continue;
      bool observed = false;
      for (const auto& [kf, idx] : mp->observations) observed = observed || index.count(kf);
      if (!observed) continue;
      const int p = variable_of(mp);
      for (const auto& [kf, idx] : mp->observations) {
        auto it = index.find(kf);
        if (it == index.end()) continue;
        const FrameData& f = *kf->data;
        BaObservation o;
        o.camera = it->second;
        o.point = p;
        o.uv = f.features.undistorted[idx];
        o.u_right = f.u_right[idx];
        o.inv_sigma2 = f.pyramid->inv_sigma2[f.features.keypoints[idx].octave];
        problem_.observations.push_back(o);
      }
    }
}

BaResult GlobalBa::solve(int iterations, const std::atomic<bool>* abort) const {
  BaConfig cfg;
  cfg.first_iterations = iterations;
  cfg.second_iterations = 0;
  return bundle_adjust(problem_, cfg, abort);
}

bool GlobalBa::apply(const BaResult& r) {
  if (r.aborted || r.T_cam_world.size() != cameras_.size()) return false;
  for (size_t m = 0; m < maps_.size(); ++m)
    if (maps_[m]->big_change_index() != change_index_[m]) return false;
  // Optimised keyframes; each one's correction as a right factor on T_cam_world.
  std::map<KeyFrame*, SE3, ById> correction;
  for (size_t c = 0; c < cameras_.size(); ++c) {
    if (cameras_[c]->bad) continue;
    correction[cameras_[c].get()] = cameras_[c]->T_world_cam() * r.T_cam_world[c];
    cameras_[c]->T_cam_world = r.T_cam_world[c];
  }
  std::unordered_set<MapPoint*> optimised;
  for (size_t p = 0; p < points_.size(); ++p)
    for (const auto& mp : points_[p]) {
      optimised.insert(mp.get());
      if (!mp->bad) mp->position = r.points[p];
    }
  for (Map* map : maps_) {
    // Keyframes created meanwhile keep their pose relative to the nearest optimised anchor.
    std::map<KeyFrame*, SE3, ById> moved_old_pose;
    for (const auto& kf : map->keyframes()) {
      if (correction.count(kf.get())) continue;
      KeyFrame* anc = kf->anchor();
      while (anc && !correction.count(anc)) anc = anc->anchor();
      if (!anc) continue;
      const SE3 T_kf_anc_old = kf->T_cam_world * (anc->T_cam_world * correction[anc].inverse()).inverse();
      moved_old_pose[kf.get()] = kf->T_cam_world;
      kf->T_cam_world = T_kf_anc_old * anc->T_cam_world;
    }
    for (const auto& mp : map->map_points()) {
      if (optimised.count(mp.get())) continue;
      auto it = moved_old_pose.find(mp->reference);
      if (it != moved_old_pose.end()) mp->position = mp->reference->T_world_cam() * (it->second * mp->position);
    }
    for (const auto& mp : map->map_points()) map->update_map_point(mp.get());
    map->note_big_change();  // tracking re-derives its last pose from its reference keyframe
  }
  return true;
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
