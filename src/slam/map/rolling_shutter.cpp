#include "slam/map/rolling_shutter.h"

#include <Eigen/Geometry>

namespace cslam {

int compensate_rolling_shutter(const PinholeCamera& camera, double bf, const SE3& T_lastrow_cam, OrbFeatures& features,
                               std::vector<float>& depth, std::vector<float>& u_right) {
  // T_lastrow_cam ~ [I + [w]x | t]: a point X in the middle row's camera is at X + w x X + t in
  // the last row's. A row at fraction s of the half readout (s in [-1, 1]) sees it at
  // X + s (w x X + t), so X = X_row - s (w x X_row + t) to first order.
  const Eigen::AngleAxisd aa(T_lastrow_cam.rotation());
  const Eigen::Vector3d w = aa.angle() * aa.axis(), t = T_lastrow_cam.translation();
  const double half_height = 0.5 * camera.height;
  int moved = 0;
  for (size_t i = 0; i < features.keypoints.size(); ++i) {
    const double s = (features.keypoints[i].pt.y - half_height) / half_height;
    Eigen::Vector2d& und = features.undistorted[i];
    const bool has_depth = depth[i] > 0;
    // Without depth only the rotation moves the ray (a ray at depth 1; the translation would
    // need the unknown depth).
    const double z = has_depth ? double(depth[i]) : 1.0;
    const Eigen::Vector3d X_row = camera.unproject(und.x(), und.y(), z);
    Eigen::Vector3d X = X_row - s * w.cross(X_row);
    if (has_depth) X -= s * t;
    if (!(X.z() > 0)) continue;
    und = camera.project(X);
    if (has_depth) {
      depth[i] = float(X.z());
      u_right[i] = float(und.x() - bf / X.z());
    }
    ++moved;
  }
  return moved;
}

}  // namespace cslam
