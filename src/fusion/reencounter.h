#pragma once
// Re-encounters inside a fused group: after two maps were fused, their robots (or a robot on a
// later day and the map of an earlier one) keep meeting each other's places. Each such place pair
// is a loop closure across two maps of one group: the query map has drifted from the other since
// they last met. The correction mirrors loop closing (src/loopclosing) with the other map held
// fixed: the query keyframe's neighbourhood moves rigidly onto the pose the verification measured,
// the query map's keyframes that already hang on the group (observers of points linked by earlier
// seams) stay where they are, and the query map's essential graph spreads the difference between
// the two; points follow their reference keyframes. The fusion manager then links the points the
// two maps share around the pair (a seam) and re-runs the group's global BA with every link.
#include <set>
#include <vector>

#include "geometry/se3.h"
#include "slam/map/map.h"

namespace cslam {

struct ReencounterConfig {
  bool enabled = true;
  int min_keyframe_gap = 10;           // keyframes of the query map between two re-encounters with one map
  int covisibility_edge_weight = 100;  // essential graph: strong covisibility edges
  int pose_graph_iterations = 20;
};

struct ReencounterCorrection {
  SE3 T_correction;  // corrected^-1 * old pose of the query keyframe (identity: no drift)
  int rigid = 0;     // keyframes moved rigidly with the query keyframe
  int anchors = 0;   // keyframes held where they were (linked to the group before)
  int graph_edges = 0;
  bool pose_graph_converged = false;
  double pose_graph_ms = 0;
};

// [unique lock on the query map; the candidate's map locked at least shared]
// T_kf_world_measured: the query keyframe's pose as the verification measured it against the
// candidate (whose map is in the same frame): S_query_candidate * T_candidate_world.
// anchor_points: points of the query map linked across maps by earlier seams.
ReencounterCorrection correct_reencounter(Map& query_map, KeyFrame& kf, const SE3& T_kf_world_measured,
                                          const std::vector<MapPointPtr>& anchor_points,
                                          const ReencounterConfig& config);

}  // namespace cslam
