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
  // No lock needed. Stops early (aborted) when *abort becomes true.
  BaResult solve(int iterations, const std::atomic<bool>* abort) const;
  // [no lock held]
  std::vector<Map*> maps() const { return maps_; }
  // [unique locks on every map] False (nothing written) if any map had a big change since the
  // snapshot or the result was aborted.
  bool apply(const BaResult& result);

  std::size_t num_keyframes() const { return cameras_.size(); }
  std::size_t num_points() const { return problem_.points.size(); }

 private:
  std::vector<Map*> maps_;
  std::vector<std::uint64_t> change_index_;
  BaProblem problem_;
  std::vector<KeyFramePtr> cameras_;
  std::vector<std::vector<MapPointPtr>> points_;  // per variable: every map point it stands for
};

// One global BA over `map` on the calling thread (snapshot under the shared lock, solve without
// it, apply under the unique lock): the refinement at the end of a session. False if the map has
// fewer than 3 keyframes or moved meanwhile.
bool run_global_ba_once(Map& map, int iterations);

}  // namespace cslam
