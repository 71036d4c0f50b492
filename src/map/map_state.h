#pragma once
// A map as plain values: what a snapshot holds of one Map, read in one consistent pass under the
// map's shared lock (export_map_state) and rebuilt into a live Map (restore_map). Graph links are
// ids instead of pointers; the immutable FrameData is shared, not copied, so the export is a
// cheap copy and the lock is held briefly. No protobuf here: proto/snapshot_adapter converts.
#include <memory>
#include <optional>
#include <vector>

#include "map/map.h"

namespace cslam {

class Vocabulary;

struct KeyFrameState {
  KeyFrameId id;
  std::shared_ptr<const FrameData> data;
  SE3 T_cam_world;
  std::optional<KeyFrameId> parent;
  std::vector<std::pair<KeyFrameId, int>> connections;  // covisibility: keyframe, weight
  std::vector<KeyFrameId> loop_edges;
  bool first_connection = true;
  std::optional<KeyFrameId> creation_reference;  // only while awaiting its first connection
  SE3 T_cam_creation_ref;
};

struct MapPointState {
  MapPointId id;
  Eigen::Vector3d position = Eigen::Vector3d::Zero(), normal = Eigen::Vector3d::Zero();
  Descriptor descriptor{};
  double min_distance = 0, max_distance = 0;
  std::vector<std::pair<KeyFrameId, int>> observations;  // keyframe, keypoint index
  std::optional<KeyFrameId> reference;
  int visible = 1, found = 1;
  cv::Vec3b color{0, 0, 0};
  std::uint32_t first_keyframe_seq = 0;
  std::size_t flat_begin = 0, flat_end = 0;  // export only: range in MapState::flat_observations
};

struct MapState {
  ClientId client = 0;
  int index = 0;
  int group = -1;  // fused group (set by the system; -1: none)
  std::optional<KeyFrameId> origin;
  std::vector<KeyFrameState> keyframes;  // sorted by id
  std::vector<MapPointState> points;     // good points only
  // export only (empty after tidy_map_state): every point's observations, back to back.
  std::vector<std::pair<KeyFrameId, int>> flat_observations;
};

// [shared] The caller holds map.mutex (shared): plain copies only, to keep the hold short.
// Culled keyframes and bad points are left out. Then, without the lock, tidy_map_state keeps
// links inside this map only, drops points left without observations and sorts by id (a
// deterministic file).
MapState export_map_state(const Map& map);
void tidy_map_state(MapState& state);

// Rebuilds a Map from its state. Throws InputError(source, ...) when the state is inconsistent
// (unknown keyframe ids in links, keypoint indices out of range, duplicate ids). Fills the
// keyframe database from each keyframe's BoW vector.
std::shared_ptr<Map> restore_map(const MapState& state, std::shared_ptr<IdAllocator> ids, const std::string& source);

// Recomputes what a FrameData derives from its stored fields: the feature grid and, with a
// vocabulary, the BoW and feature vectors.
void derive_frame_data(FrameData& data, const Vocabulary* vocabulary, int bow_levels_up);

}  // namespace cslam
