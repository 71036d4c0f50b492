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
#include <cstdint>
#include <map>
#include <set>
#include <vector>

#include "geometry/se3.h"
#include "slam/loop/essential_graph.h"
#include "slam/loop/pose_graph.h"
#include "slam/map/map.h"

namespace cslam {

struct ReencounterConfig {
  bool enabled = true;
  int min_keyframe_gap = 10;           // keyframes of the query map between two re-encounters with one map
  int covisibility_edge_weight = 100;  // essential graph: strong covisibility edges
  int pose_graph_iterations = 20;
  // A drift that moves the query keyframe's image by less than this (pixels at its median depth,
  // see correction_px) is below what its features measure: the seam is linked and the group BA run,
  // but no keyframe is moved, so tracking, local mapping and the running BAs keep their work.
  // 0: correct every drift.
  double min_correction_px = 1.0;
};

struct ReencounterCorrection {
  SE3 T_correction;          // corrected^-1 * old pose of the query keyframe (identity: no drift)
  double correction_px = 0;  // how far the correction moves the query keyframe's image points
  bool skipped = false;      // below min_correction_px: nothing moved
  int rigid = 0;             // keyframes moved rigidly with the query keyframe
  int anchors = 0;           // keyframes held where they were (linked to the group before)
  int graph_edges = 0;
  bool pose_graph_converged = false;
  double pose_graph_ms = 0;
};

// The correction in three steps, so that the query map is held exclusively only while it is
// written (tracking reads it under shared locks and goes on while the graph is solved):
//   1. plan_reencounter [query map locked at least shared; the candidate's map too]: the rigid
//      set and its corrected poses, the anchors, the essential graph between them;
//   2. solve_reencounter [no lock]: the pose graph;
//   3. apply_reencounter [unique lock on the query map]: false (nothing written) if the map had a
//      big change (loop correction, global BA) since step 1.
// A plan whose correction is below min_correction_px is marked skipped at step 1; steps 2 and 3
// then do nothing (3 returns true). Keyframes created meanwhile follow
//      their anchor, and their points follow them, as after a global BA.
// T_kf_world_measured: the query keyframe's pose as the verification measured it against the
// candidate (whose map is in the same frame): S_query_candidate * T_candidate_world.
// anchor_points: points of the query map linked across maps by earlier seams.
struct ReencounterPlan {
  ReencounterCorrection summary;
  std::uint64_t change_index = 0;                    // the query map's big_change_index() at step 1
  std::vector<KeyFramePtr> keyframes;                // every keyframe of the map at step 1, kept alive
  std::map<KeyFrame*, SE3, ById> rigid_T_cam_world;  // the rigid set's corrected poses
  EssentialGraph graph;
  PoseGraphResult result;
};
ReencounterPlan plan_reencounter(const Map& query_map, const KeyFrame& kf, const SE3& T_kf_world_measured,
                                 const std::vector<MapPointPtr>& anchor_points, const ReencounterConfig& config);
// The image displacement of a correction for a camera of focal length focal_px that sees its scene at
// median_depth_m: focal_px * (|t| / depth + angle), the pixels by which it moves what the camera saw.
double correction_px(const SE3& T_correction, double focal_px, double median_depth_m);
void solve_reencounter(ReencounterPlan& plan, const ReencounterConfig& config);
bool apply_reencounter(Map& query_map, ReencounterPlan& plan);

// The three steps at once [unique lock on the query map; the candidate's map locked at least
// shared].
ReencounterCorrection correct_reencounter(Map& query_map, KeyFrame& kf, const SE3& T_kf_world_measured,
                                          const std::vector<MapPointPtr>& anchor_points,
                                          const ReencounterConfig& config);

}  // namespace cslam
