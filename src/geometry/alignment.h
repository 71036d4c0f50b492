#pragma once
// Closed-form alignment of corresponding 3D point sets (Umeyama 1991; Horn's method with scale).
#include <vector>

#include <Eigen/Core>

#include "geometry/se3.h"

namespace cslam {

// Least-squares similarity mapping src onto dst: dst ~ s R src + t.
// With with_scale = false, s = 1. Needs at least 3 non-degenerate points; ok = false otherwise.
struct UmeyamaResult {
  bool ok = false;
  Sim3 T_dst_src;
  double rmse = 0;
};
UmeyamaResult umeyama(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                      bool with_scale);

// Same, on n points given by pointers (no allocation; used in RANSAC inner loops). rmse is filled.
UmeyamaResult umeyama(const Eigen::Vector3d* src, const Eigen::Vector3d* dst, int n, bool with_scale);

}  // namespace cslam
