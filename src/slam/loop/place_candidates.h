#pragma once
// Place-recognition candidates of a keyframe in a map's database, as groups for the consistency
// check; shared by loop detection (own map) and overlap detection (other clients' maps).
#include <functional>
#include <vector>

#include "slam/loop/consistency.h"
#include "slam/map/map.h"

namespace cslam {

// Lowest BoW similarity between a keyframe and its covisible keyframes (1 if it has none): the
// minimum score a place candidate must reach. The caller holds the keyframe's map mutex.
double min_covisible_score(const KeyFrame& kf);

// Candidates of `bow` in `map` above `min_score` (ORB-SLAM2 query refinements), each with its
// covisible keyframes as group members. The caller holds `map.mutex` (shared).
std::vector<ConsistencyChecker::Group> query_candidate_groups(const Map& map, const BowVector& bow, double min_score,
                                                              const std::function<bool(KeyFrameId)>& exclude);

}  // namespace cslam
