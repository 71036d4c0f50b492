#pragma once
// The whole collaborative system as plain values, for snapshots: every client's SLAM state, each
// map tagged with its fused group (maps of one group share one frame).
#include <vector>

#include "slam/client_slam_state.h"

namespace cslam {

struct SystemState {
  std::vector<ClientSlamState> clients;
};

}  // namespace cslam
