#pragma once
// Map fusion's own state as plain values, for snapshots: the seams that hold each fused group
// together (the points both maps hold, linked; the cross-map covisibility) and when each pair of
// maps was last linked. Maps are named by (client, index), points and keyframes by their ids.
#include <cstdint>
#include <utility>
#include <vector>

#include "core/ids.h"

namespace cslam {

struct MapKey {
  ClientId client = 0;
  int index = 0;
  friend bool operator==(MapKey a, MapKey b) { return a.client == b.client && a.index == b.index; }
  friend bool operator<(MapKey a, MapKey b) { return a.client != b.client ? a.client < b.client : a.index < b.index; }
};

struct SeamEdgeState {
  KeyFrameId kept, moved;
  int weight = 0;
};

struct SeamState {
  MapKey kept_map, moved_map;                            // kept: the side that did not move
  std::vector<std::pair<MapPointId, MapPointId>> links;  // (kept point, moved point)
  std::vector<SeamEdgeState> edges;
};

// A pair of maps last linked (fusion or re-encounter) when the query map had seen this many
// keyframes; keyframes_seen says how many it has seen now. Re-encounters wait for a gap.
struct MapLinkState {
  MapKey query, other;
  int query_keyframes_at_link = 0;
};

// Place recognition's run of consistent detections of `other` by `query`'s keyframes (the
// ConsistencyChecker's groups: the other map's keyframe ids, and how many updates in a row).
struct ConsistencyState {
  MapKey query, other;
  std::vector<std::pair<std::vector<KeyFrameId>, int>> groups;
};

struct FusionState {
  std::vector<SeamState> seams;
  std::vector<ConsistencyState> consistency;
  std::vector<MapLinkState> last_links;
  std::vector<std::pair<MapKey, int>> keyframes_seen;
};

}  // namespace cslam
