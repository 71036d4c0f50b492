// FusionManager's re-encounters (declared in fusion/fusion_manager.h): place pairs between maps
// that are already in one group, and their correction (fusion/reencounter.h).
#include <cmath>
#include <shared_mutex>

#include "core/log.h"
#include "core/stopwatch.h"
#include "fusion/fusion_manager.h"
#include "slam/map/map_locks.h"

namespace cslam {

bool FusionManager::try_reencounter(const Pending& p, const std::vector<Registered>& same_group, const BowVector& bow,
                                    double min_score) {
  for (const auto& other_reg : same_group) {
    auto other = other_reg.map.lock();
    if (!other) continue;
    {
      // Not again right after the last link of this pair: those places are tied already.
      std::lock_guard<std::mutex> lock(state_mutex_);
      auto it = last_link_.find({p.map.get(), other.get()});
      if (it != last_link_.end() && keyframes_seen_[p.map.get()] - it->second < config_.reencounter.min_keyframe_gap)
        continue;
    }
    const auto found = verified_candidate(p, *other, other_reg.client, bow, min_score);
    if (!found) continue;
    reencounter(p, other, other_reg.client, found->candidate, found->v, found->hit);
    return true;
  }
  return false;
}

void FusionManager::reencounter(const Pending& p, const std::shared_ptr<Map>& other, ClientId other_client,
                                const KeyFramePtr& candidate, const OverlapVerifyResult& v,
                                std::chrono::steady_clock::time_point hit) {
  std::vector<MapPointPtr> anchors;  // the query map's points linked by earlier seams
  GroupId group;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    group = group_.at(p.map.get());
    if (group_.at(other.get()) != group) return;
    for (const auto& s : seams_) {
      const auto kept = s.kept_map.lock(), moved = s.moved_map.lock();
      for (const auto& l : s.seam.points) {
        if (kept.get() == p.map.get()) anchors.push_back(l.kept);
        if (moved.get() == p.map.get()) anchors.push_back(l.moved);
      }
    }
  }
  stop_group_ba();  // cut short: what it solved so far is written before the correction
  std::unique_lock<std::shared_mutex> moving_maps(links_mutex_);
  // The robots' tracking reads both maps under shared locks: it goes on while the correction is
  // planned and solved and the seam matched; only writing them holds a map exclusively.
  Stopwatch locked;  // exclusive holds of the maps, summed: the robots' tracking waits this long at most
  double correction_ms = 0, seam_ms = 0;
  ReencounterPlan plan;
  {
    auto locks = lock_maps<std::shared_lock<std::shared_mutex>>({p.map.get(), other.get()});
    if (p.kf->bad || candidate->bad) return;
    const SE3 T_kf_world_measured = v.S_query_candidate.to_se3() * candidate->T_cam_world;
    plan = plan_reencounter(*p.map, *p.kf, T_kf_world_measured, anchors, config_.reencounter);
  }
  if (!plan.summary.skipped) {  // below a pixel: no solve, and no exclusive hold of the map
    solve_reencounter(plan, config_.reencounter);
    std::unique_lock<std::shared_mutex> lock(p.map->mutex);
    locked.reset();
    const bool applied = apply_reencounter(*p.map, plan);
    correction_ms = locked.ms();
    if (!applied) {
      logger("fusion")->info("client {} re-encounter of client {}'s map dropped: the map moved while it was solved",
                             p.client, other_client);
      return;
    }
  }
  const ReencounterCorrection& c = plan.summary;
  std::vector<SeamLink> pairs;
  {
    auto locks = lock_maps<std::shared_lock<std::shared_mutex>>({p.map.get(), other.get()});
    if (!p.kf->bad && !candidate->bad) pairs = match_seam(*candidate, *p.kf, config_.seam);
  }
  Seam seam;
  {
    auto locks = lock_maps<std::unique_lock<std::shared_mutex>>({p.map.get(), other.get()});
    locked.reset();
    seam = link_seam(*other, *p.map, pairs, config_.seam);
    seam_ms = locked.ms();
  }
  FusionEvent e = link_event("reencounter", p, other_client, group, candidate, v, seam, hit);
  e.keyframes_moved = c.rigid;
  e.keyframes_kept = c.anchors;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    events_.push_back(e);
    seams_.push_back({other, p.map, std::move(seam)});
    last_link_[{p.map.get(), other.get()}] = keyframes_seen_[p.map.get()];
    consistency_.erase({p.map.get(), other.get()});
  }
  moving_maps.unlock();
  logger("fusion")->info(
      "client {} re-encountered client {}'s map (group {}): {} inliers, drift {:.1f} cm / {:.2f} deg ({:.2f} px) "
      "{} ({} keyframes rigid, {} anchored, pose graph {:.1f} ms), {} seam points, maps "
      "locked {:.1f} ms (correction {:.1f}, seam {:.1f}), {:.1f} ms from detection",
      p.client, other_client, group.value(), v.final_inliers, 100 * c.T_correction.translation().norm(),
      Eigen::AngleAxisd(c.T_correction.rotation()).angle() * 180 / M_PI, c.correction_px,
      c.skipped ? "below what its features measure, not corrected" : "corrected", c.rigid, c.anchors, c.pose_graph_ms,
      e.seam_points, correction_ms + seam_ms, correction_ms, seam_ms, e.duration_ms);
  start_group_ba(group);
}

}  // namespace cslam
