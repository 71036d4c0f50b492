#pragma once
// A tracked frame as the trajectory keeps it: its pose relative to the keyframe it was tracked
// against (ORB-SLAM's relative frame poses), so loop closing and fusion move it with that
// keyframe. When local mapping culls the keyframe, the culled keyframe keeps its spanning-tree
// parent and its pose relative to it (KeyFrame::T_cam_parent), and the frame follows the chain.
#include <vector>

#include "slam/map/keyframe.h"

namespace cslam {

struct FrameRecord {
  double timestamp = 0;
  KeyFramePtr reference;
  SE3 T_cam_ref;
  int map_index = 0;
};

// The live keyframe up the reference's chain of culled keyframes and the frame's pose relative
// to it (null if the chain ends in a culled root). Caller holds the map's lock (shared).
struct LiveReference {
  const KeyFrame* keyframe = nullptr;
  SE3 T_cam_ref;
  // The frame's pose at the keyframe's current estimate (keyframe not null).
  SE3 T_world_cam() const { return (T_cam_ref * keyframe->T_cam_world).inverse(); }
};
LiveReference live_reference(const FrameRecord& record);

// Moves every record whose reference was culled onto its live ancestor (the composition
// live_reference() would do, done once, so the result is bit-identical): the culled keyframes,
// with their features and map points, are then freed instead of being held by the frames that
// were tracked against them. Caller holds the locks of the maps the records refer to (shared).
void reanchor_culled(std::vector<FrameRecord>& records);

}  // namespace cslam
