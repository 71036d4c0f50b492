#pragma once
// A keyframe's current pose as the dense map reads it: camera-to-world in the frame of the group
// its map belongs to (the map's own frame, labelled client * 100 + map index, until map fusion
// joins it to others).
#include "core/ids.h"
#include "geometry/se3.h"

namespace cslam {

struct KeyframePose {
  KeyFrameId id;
  int group = -1;
  int map = 0;  // index of the client's map
  SE3 T_world_cam;
};

}  // namespace cslam
