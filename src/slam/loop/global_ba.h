#pragma once
// Global bundle adjustment over one map (after a loop closure) or over every map of a fused group
// (after a map fusion), run without holding any map lock while it solves:
//   1. snapshot() under shared locks: keyframes, points and observations; points known to be the
//      same physical point in two maps (fusion seams) become one variable;
//   2. solve() without locks, interruptible;
//   3. apply() under unique locks, only if no map had a big change (loop correction, fusion,
//      another global BA) since the snapshot: optimised keyframes and points take the result,
//      keyframes created meanwhile follow their anchor (spanning-tree parent, or the keyframe they
//      were tracked against) and their points follow them, as ORB-SLAM2 merges its global BA.
#include <atomic>
#include <cstdint>
#include <map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "slam/map/map.h"
#include "optimize/bundle_adjustment.h"

namespace cslam {

class GlobalBa {
 public:
  // [shared locks on every map] The first map's origin keyframe is held fixed (the gauge).
  // `same_points`: pairs of points (in different maps) estimated as one.
  void snapshot(const std::vector<Map*>& maps,
                const std::vector<std::pair<MapPointPtr, MapPointPtr>>& same_points = {});
  // No lock needed. Stops early (aborted) when *abort becomes true; with keep_progress the result
  // is then the last accepted iterate (partial), which apply() takes like a completed solve.
  BaResult solve(int iterations, const std::atomic<bool>* abort, bool keep_progress = false) const;
  // [no lock held]
  std::vector<Map*> maps() const { return maps_; }
  // [unique locks on every map] False (nothing written) if any map had a big change since the
  // snapshot or the result was aborted without its progress.
  bool apply(const BaResult& result);
  // [unique lock on maps()[m]] The result for one map alone (its keyframes, its points, its
  // keyframes created meanwhile), so that each robot's tracking waits only while its own map is
  // written. False (nothing written) if that map had a big change since the snapshot or the
  // result was aborted without its progress. apply() is apply_map() over every map once each
  // passed the check.
  bool apply_map(std::size_t m, const BaResult& result);

  std::size_t num_keyframes() const { return cameras_.size(); }
  std::size_t num_points() const { return problem_.points.size(); }

 private:
  std::vector<Map*> maps_;
  std::vector<std::uint64_t> change_index_;
  bool usable(const BaResult& r) const;
  // [unique lock on maps_[m]] Points of map m that were not optimised and whose reference keyframe
  // was carried (created meanwhile) move with it; moved_old_pose: each carried keyframe's pose before.
  void move_followers(std::size_t m, const std::map<KeyFrame*, SE3, ById>& moved_old_pose);
  BaProblem problem_;
  std::vector<KeyFramePtr> cameras_;
  std::vector<std::size_t> camera_map_;  // per camera: its map's index in maps_
  // per map: (variable, point) for every point of that map that a variable stands for
  std::vector<std::vector<std::pair<int, MapPointPtr>>> map_points_;
};

// [unique lock on `map`] After an optimisation moved some of its keyframes (`old_pose`: each moved
// keyframe's pose before), every other keyframe not in `known` (one created after the
// optimisation's snapshot) keeps its pose relative to the nearest anchor that moved (spanning-tree
// parent, or the keyframe it was tracked against). Returns the carried keyframes' poses before, so
// that their points can follow them.
std::map<KeyFrame*, SE3, ById> carry_new_keyframes(const Map& map, const std::map<KeyFrame*, SE3, ById>& old_pose,
                                                   const std::unordered_set<const KeyFrame*>& known = {});

// [unique lock on `map`] After a correction moved keyframes (`old_pose`: each moved keyframe's pose
// before), every point whose reference keyframe moved, less those in `skip` (placed otherwise),
// keeps its position in that keyframe's frame; then every point's normal and distance bounds are
// brought up to date (Map::update_map_point).
void points_follow_references(Map& map, const std::map<KeyFrame*, SE3, ById>& old_pose,
                              const std::unordered_set<MapPoint*>& skip = {});

// One global BA over `map` on the calling thread (snapshot under the shared lock, solve without
// it, apply under the unique lock): the refinement at the end of a session. False if the map has
// fewer than 3 keyframes or moved meanwhile.
bool run_global_ba_once(Map& map, int iterations);

}  // namespace cslam
