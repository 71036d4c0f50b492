#pragma once
#include <string>
#include <vector>

#include "core/ids.h"
#include "geometry/se3.h"

namespace cslam {

// One accepted overlap between two clients' maps (or a loop within one client).
struct FusionEvent {
  double wall_time_s = 0;  // seconds since the system started
  ClientId client_a = 0, client_b = 0;
  GroupId group;  // the group after the fusion
  int inliers = 0;
  double duration_ms = 0;  // detection hit to fused map
  std::string kind = "fusion";
  double query_timestamp = 0, candidate_timestamp = 0;  // frame times of the two keyframes
  SE3 T_query_candidate;                        // verified camera-to-camera transform (p_query = T * p_candidate)
  int seam_points = 0;                          // points found in both maps and linked (estimated as one)
  int seam_edges = 0;                           // cross-map covisibility edges (keyframe pairs sharing >= 15 points)
  int keyframes_moved = 0, keyframes_kept = 0;  // keyframes of the moved and the kept group
};

// Global BA over the maps of fused groups (background, after each fusion).
struct GroupBaStats {
  int started = 0, completed = 0, discarded = 0;
  int cut_short = 0;       // of the completed: stopped by the next link, what they solved written
  std::vector<double> ms;  // completed runs (cut short ones too), wall time
  int last_keyframes = 0, last_points = 0, last_linked_points = 0;
};

}  // namespace cslam
