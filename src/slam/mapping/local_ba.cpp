// Local bundle adjustment: the new keyframe and its covisible keyframes are free, keyframes that
// see their points but are not covisible are fixed. Data is copied under the shared map lock,
// solved without holding it (tracking goes on), and written back under the unique lock.
#include <algorithm>
#include <shared_mutex>
#include <unordered_map>

#include "core/stopwatch.h"
#include "slam/mapping/local_mapper.h"

namespace cslam {

namespace {
StereoIntrinsics intrinsics_of(const KeyFrame& kf) {
  const auto& c = kf.data->camera;
  return {c.fx, c.fy, c.cx, c.cy, kf.data->rgbd.bf};
}
}  // namespace

void LocalMapper::local_bundle_adjustment(KeyFrame* kf) {
  Stopwatch sw;
  BaProblem prob;
  std::vector<KeyFramePtr> cameras;
  std::vector<MapPointPtr> points;
  std::vector<std::pair<KeyFrame*, MapPoint*>> obs_refs;
  std::uint64_t change_index = 0;
  {
    std::shared_lock<std::shared_mutex> lock(map_->mutex);
    if (kf->bad) return;
    change_index = map_->big_change_index();
    std::unordered_map<KeyFrame*, int> cam_index;
    auto add_camera = [&](KeyFrame* k, bool fixed) {
      auto p = map_->shared(k);
      if (!p) return -1;
      cam_index[k] = int(cameras.size());
      cameras.push_back(p);
      prob.cameras.push_back({k->T_cam_world, intrinsics_of(*k), fixed || k == map_->origin().get()});
      return cam_index[k];
    };
    add_camera(kf, false);
    for (KeyFrame* n : kf->best_covisibles(std::size_t(std::max(0, config_.local_ba_max_keyframes - 1))))
      if (!n->bad) add_camera(n, false);
    const size_t num_local = cameras.size();
    ba_points_seen_.clear();
    for (size_t c = 0; c < num_local; ++c)
      for (const auto& mp : cameras[c]->map_points)
        if (mp && ba_points_seen_.insert(mp.get()) && !mp->bad) {
          points.push_back(mp);
          prob.points.push_back(mp->position);
        }
    std::vector<int> keypoint;  // of each observation
    for (size_t p = 0; p < points.size(); ++p) {
      for (const auto& [okf, idx] : points[p]->observations) {
        if (okf->bad) continue;
        auto it = cam_index.find(okf);
        int c = it == cam_index.end() ? add_camera(okf, true) : it->second;
        if (c < 0) continue;
        BaObservation o;
        o.camera = c;
        o.point = int(p);
        o.uv.setZero();  // filled below
        prob.observations.push_back(o);
        obs_refs.emplace_back(okf, points[p].get());
        keypoint.push_back(idx);
      }
    }
    // The keypoints' data in a second pass: each is a cache miss in its keyframe's arrays, and
    // with the keyframe and keypoint known the next ones are fetched while one is read.
    const std::size_t n = keypoint.size();
    constexpr std::size_t kAhead = 8;
    auto prefetch = [&](std::size_t i) {
      const FrameData& f = *obs_refs[i].first->data;
      const auto k = std::size_t(keypoint[i]);
      __builtin_prefetch(&f.features.undistorted[k]);
      __builtin_prefetch(&f.u_right[k]);
      __builtin_prefetch(&f.features.keypoints[k].octave);
    };
    for (std::size_t i = 0; i < std::min(n, kAhead); ++i) prefetch(i);
    for (std::size_t i = 0; i < n; ++i) {
      if (i + kAhead < n) prefetch(i + kAhead);
      const FrameData& f = *obs_refs[i].first->data;
      const auto k = std::size_t(keypoint[i]);
      BaObservation& o = prob.observations[i];
      o.uv = f.features.undistorted[k];
      o.u_right = f.u_right[k];
      o.inv_sigma2 = f.pyramid->inv_sigma2[f.features.keypoints[k].octave];
    }
  }
  if (prob.observations.empty()) return;
  const BaResult res = bundle_adjust(prob, config_.ba);
  {
    MapWriteLock lock(*map_);
    // The map was moved meanwhile (fusion, loop correction): the solution is in the old frame.
    if (map_->big_change_index() != change_index) return;
    for (size_t i = 0; i < prob.observations.size(); ++i) {
      if (res.inlier[i]) continue;
      KeyFrame* okf = obs_refs[i].first;
      const MapPointPtr& mp = points[prob.observations[i].point];
      if (!okf->bad && !mp->bad && mp->in_keyframe(okf)) map_->erase_observation(okf, mp);
    }
    for (size_t c = 0; c < cameras.size(); ++c)
      if (!prob.cameras[c].fixed && !cameras[c]->bad) cameras[c]->T_cam_world = res.T_cam_world[c];
    for (size_t p = 0; p < points.size(); ++p) {
      if (points[p]->bad) continue;
      points[p]->position = res.points[p];
      map_->update_map_point(points[p].get());
    }
  }
  std::lock_guard<std::mutex> lock(stats_mutex_);
  stats_.ba_ms.push_back(sw.ms());
}

}  // namespace cslam
