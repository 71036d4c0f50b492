#pragma once
// Walks over the voxels of placed TSDF submaps in world coordinates.
#include <cmath>

#include "navmap/submap_view.h"

namespace cslam {

// Calls f(p_world, signed_distance_m, voxel) for every observed voxel of the view with weight
// above min_weight. signed_distance_m > 0: in front of a surface (free), <= 0: at or behind it.
template <typename F>
void for_each_world_voxel(const SubmapView& view, float min_weight, F&& f) {
  const TsdfVolume& vol = *view.volume;
  const double vs = vol.config().voxel_size, trunc = vol.config().truncation;
  const Eigen::Matrix3d R = view.T_world_submap.R();
  const Eigen::Vector3d t = view.T_world_submap.translation();
  vol.for_each_observed_voxel([&](const Eigen::Vector3i& idx, const TsdfVoxel& v) {
    if (!(v.weight > min_weight) || !std::isfinite(v.sdf)) return;
    const Eigen::Vector3d p = R * ((idx.cast<double>() + Eigen::Vector3d::Constant(0.5)) * vs) + t;
    f(p, double(v.sdf) * trunc, v);
  });
}

// Calls f(p_world) for every point where the TSDF crosses zero going down along `up`: the
// surface of an upward-facing patch (floor, table top). Found between a free voxel and the
// observed occupied voxel below it along the submap axis closest to up, by linear interpolation
// (exact for a plane whatever the projective scaling of the distances).
template <typename F>
void for_each_upward_crossing(const SubmapView& view, const Eigen::Vector3d& up, float min_weight, F&& f) {
  const TsdfVolume& vol = *view.volume;
  const double vs = vol.config().voxel_size;
  const Eigen::Vector3d up_s = view.T_world_submap.R().transpose() * up;
  int axis = 0;
  up_s.cwiseAbs().maxCoeff(&axis);
  Eigen::Vector3i down = Eigen::Vector3i::Zero();
  down[axis] = up_s[axis] > 0 ? -1 : 1;
  vol.for_each_observed_voxel([&](const Eigen::Vector3i& idx, const TsdfVoxel& a) {
    if (!(a.sdf > 0.0f && a.sdf < 1.0f) || !(a.weight > min_weight)) return;
    const TsdfVoxel* b = vol.voxel(idx + down);
    if (!b || !(b->weight > min_weight) || !(b->sdf <= 0.0f)) return;
    const double s = double(a.sdf) / (double(a.sdf) - double(b->sdf));  // in (0, 1]
    const Eigen::Vector3d c = (idx.cast<double>() + Eigen::Vector3d::Constant(0.5) + s * down.cast<double>()) * vs;
    f(view.T_world_submap * c);
  });
}

}  // namespace cslam
