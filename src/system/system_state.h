#pragma once
// The whole collaborative system as plain values, for snapshots: every client's SLAM state, each
// map tagged with its fused group (maps of one group share one frame), and map fusion's seams.
#include <vector>

#include "fusion/fusion_state.h"
#include "slam/client_slam_state.h"

namespace cslam {

struct SystemState {
  std::vector<ClientSlamState> clients;
  FusionState fusion;
};

// Drops the seam links and edges that name a point or keyframe the clients' maps do not hold
// (culled between one map's copy and the seams' copy), and the seams and links of maps that are
// not there: what is left restores.
void keep_fusion_within_maps(SystemState& state);

}  // namespace cslam
