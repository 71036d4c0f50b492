#pragma once
// A map as plain values: what a snapshot holds of one Map, read in one consistent pass under the
// map's shared lock (export_map_state) and rebuilt into a live Map (restore_map). Graph links are
// ids instead of pointers; the immutable FrameData is shared, not copied, so the export is a
// cheap copy and the lock is held briefly. No protobuf here: proto/snapshot_adapter converts.
#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "slam/map/map.h"

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
  // export only (not stored in a snapshot): how often export_map_state_yielding gave the lock up
  // to a waiting writer before its copy, and whether it then copied without yielding (forced).
  int export_yields = 0;
  bool export_forced = false;
  // export only: when the copy held the map's shared lock (each attempt, the abandoned ones too).
  std::vector<std::pair<std::chrono::steady_clock::time_point, std::chrono::steady_clock::time_point>> export_holds;
};

// [shared] The caller holds map.mutex (shared): plain copies only, to keep the hold short.
// Culled keyframes and bad points are left out. Then, without the lock, tidy_map_state keeps
// links inside this map only, drops points left without observations and sorts by id (a
// deterministic file).
MapState export_map_state(const Map& map);
// [shared] The same copy into `out`, but with yield_to_writers it checks map.writers_waiting()
// before it starts and every few hundred keyframes / points, and gives up when a writer waits:
// returns false at once (`out` is partial: the caller drops it after releasing the lock).
bool export_map_state(const Map& map, MapState& out, bool yield_to_writers);
// Takes the map's shared lock itself and copies the map in one uninterrupted hold, giving the
// lock up to waiting writers (MapWriteLock) up to `max_yields` times: after each, it waits until
// the writer holds the lock and starts again once the writer is through. Then it copies without
// yielding, so it always completes (out.export_forced). `under_lock` runs in the same hold right
// after the copy (for readers that need the map exactly as copied).
MapState export_map_state_yielding(const Map& map, int max_yields = 20, const std::function<void()>& under_lock = {});
void tidy_map_state(MapState& state);

// Rebuilds a Map from its state. Throws InputError(source, ...) when the state is inconsistent
// (unknown keyframe ids in links, keypoint indices out of range, duplicate ids). Fills the
// keyframe database from each keyframe's BoW vector.
std::shared_ptr<Map> restore_map(const MapState& state, std::shared_ptr<IdAllocator> ids, const std::string& source);

// Recomputes what a FrameData derives from its stored fields: the feature grid and, with a
// vocabulary, the BoW and feature vectors.
void derive_frame_data(FrameData& data, const Vocabulary* vocabulary, int bow_levels_up);

}  // namespace cslam
