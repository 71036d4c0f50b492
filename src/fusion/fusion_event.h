#pragma once
#include <string>

#include "core/ids.h"
#include "geometry/se3.h"

namespace cslam {

// One accepted overlap between two clients' maps (or a loop within one client).
struct FusionEvent {
  double wall_time_s = 0;  // seconds since the system started
  ClientId client_a = 0, client_b = 0;
  int group = -1;          // group id after the fusion
  int inliers = 0;
  double duration_ms = 0;  // detection hit to fused map
  std::string kind = "fusion";
  double query_timestamp = 0, candidate_timestamp = 0;  // frame times of the two keyframes
  SE3 T_query_candidate;  // verified camera-to-camera transform (p_query = T * p_candidate)
};

}  // namespace cslam
