#pragma once
// What the navigation maps read: TSDF submaps placed in the world.
#include <vector>

#include "dense/tsdf_volume.h"
#include "geometry/se3.h"

namespace cslam {

// One TSDF submap (voxels in its own frame) and its pose in the world. The volume is only read
// and must outlive the call it is passed to; nullptr or a non-finite pose is skipped (counted).
struct SubmapView {
  const TsdfVolume* volume = nullptr;
  SE3 T_world_submap;
};

using SubmapViews = std::vector<SubmapView>;

// True if the view can be used (a volume and a finite pose).
inline bool usable(const SubmapView& v) { return v.volume != nullptr && v.T_world_submap.is_finite(); }

}  // namespace cslam
