#pragma once
// One client's SLAM state as plain values, for snapshots: its maps, its frame trajectory (each
// frame relative to a keyframe of its map, as ClientSlam keeps it), its id counters and the
// sender's sequence number of the last frame processed.
#include <array>
#include <cstdint>
#include <vector>

#include "io/trajectory_io.h"
#include "slam/map/map_state.h"
#include "slam/client_slam.h"

namespace cslam {

struct FrameRecordState {
  double timestamp = 0;
  int map_index = 0;
  KeyFrameId reference;  // a keyframe of that map (culled references already resolved)
  SE3 T_cam_ref;
};

struct ClientSlamState {
  ClientInfo info;
  std::uint64_t last_seq = 0;                      // sender's seq of the last frame processed
  double last_timestamp = 0;                       // of that frame
  int current_map = 0;                             // the map tracking was in
  std::array<std::uint32_t, 3> next_ids{0, 0, 0};  // next keyframe, map point and frame sequence numbers
  std::uint64_t frames_processed = 0, frames_tracked = 0, frames_lost = 0, frames_rejected = 0;
  std::vector<MapState> maps;  // maps[i].index == i
  std::vector<FrameRecordState> records;
};

// The frame trajectory of the maps sharing the fused group (MapState::group) that holds most
// frames, a map without a group being one of its own (as ClientSlam::trajectory does on the live
// state with fusion's groups), camera-to-world in that frame; `map_index` receives the included
// map with most frames (-1: none).
Trajectory state_trajectory(const ClientSlamState& state, int* map_index = nullptr);
// Keyframe poses (camera-to-world) of one map.
Trajectory state_keyframes(const MapState& map);

}  // namespace cslam
