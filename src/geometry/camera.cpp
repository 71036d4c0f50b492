#include "geometry/camera.h"

#include <cmath>
#include <cstdio>

#include "core/error.h"

namespace cslam {

bool PinholeCamera::has_distortion() const {
  for (double d : dist)
    if (d != 0.0) return true;
  return false;
}

bool same_projection(const PinholeCamera& a, const PinholeCamera& b) {
  return a.fx == b.fx && a.fy == b.fy && a.cx == b.cx && a.cy == b.cy && a.dist == b.dist && a.width == b.width &&
         a.height == b.height;
}

namespace {
std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}
}  // namespace

void PinholeCamera::validate() const {
  const std::string what = "camera '" + name + "': ";
  auto finite_pos = [](double v) { return std::isfinite(v) && v > 0; };
  if (!finite_pos(fx) || !finite_pos(fy)) throw ConfigError(what + "focal lengths must be positive");
  if (!std::isfinite(cx) || !std::isfinite(cy)) throw ConfigError(what + "principal point is not finite");
  if (width <= 0 || height <= 0) throw ConfigError(what + "image size must be positive");
  if (width < kMinCameraSide || height < kMinCameraSide)
    throw ConfigError(what + "image " + std::to_string(width) + "x" + std::to_string(height) +
                      " is below the minimum " + std::to_string(kMinCameraSide) + "x" + std::to_string(kMinCameraSide) +
                      " (the feature detector finds nothing in a smaller image)");
  if (!(cx >= 0 && cx <= width) || !(cy >= 0 && cy <= height))
    throw ConfigError(what + "principal point (" + num(cx) + ", " + num(cy) + ") is outside the " +
                      std::to_string(width) + "x" + std::to_string(height) + " image");
  auto focal_ok = [](double f, int side) { return f >= kMinFocalPerSide * side && f <= kMaxFocalPerSide * side; };
  if (!focal_ok(fx, width) || !focal_ok(fy, height))
    throw ConfigError(what + "focal lengths fx = " + num(fx) + ", fy = " + num(fy) + " are outside [" +
                      num(kMinFocalPerSide) + ", " + num(kMaxFocalPerSide) + "] x the image size " +
                      std::to_string(width) + "x" + std::to_string(height) +
                      " (a field of view between 157 and 5.7 degrees)");
  if (!finite_pos(depth_factor)) throw ConfigError(what + "depth_factor must be positive");
  if (!finite_pos(depth_scale_correction)) throw ConfigError(what + "depth_scale_correction must be positive");
  for (double d : dist)
    if (!std::isfinite(d)) throw ConfigError(what + "distortion coefficient is not finite");
  if (!std::isfinite(readout_time) || readout_time < 0 || readout_time > 1.0)
    throw ConfigError(what + "readout_time must be in [0, 1] s");
}

namespace {
// The colour cameras of the TUM sequences (Kinect v1 for fr1 and fr2, Asus Xtion for fr3) are
// rolling-shutter CMOS sensors at 30 Hz. 20 ms from first to last row is the readout at which
// tracking keeps the most inliers on fr1/rpy and fr1/desk (no ground truth involved; docs/slam.md);
// half of it keeps most of the gain, twice it costs accuracy, so the value errs low.
constexpr double kTumReadoutTime = 0.020;
}  // namespace

Eigen::Vector2d PinholeCamera::distort_pixel(const Eigen::Vector2d& undistorted) const {
  const double x = (undistorted.x() - cx) / fx, y = (undistorted.y() - cy) / fy;
  const double k1 = dist[0], k2 = dist[1], p1 = dist[2], p2 = dist[3], k3 = dist[4];
  const double r2 = x * x + y * y;
  const double radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
  const double xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
  const double yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
  return {fx * xd + cx, fy * yd + cy};
}

PinholeCamera camera_tum_fr1() {
  PinholeCamera c;
  c.name = "tum1";
  c.fx = 517.306408;
  c.fy = 516.469215;
  c.cx = 318.643040;
  c.cy = 255.313989;
  c.dist = {0.262383, -0.953104, -0.005358, 0.002628, 1.163314};
  c.readout_time = kTumReadoutTime;
  return c;
}

PinholeCamera camera_tum_fr2(bool depth_correction) {
  PinholeCamera c;
  c.name = depth_correction ? "tum2-corrected" : "tum2";
  c.fx = 520.908620;
  c.fy = 521.007327;
  c.cx = 325.141442;
  c.cy = 249.701764;
  c.dist = {0.231222, -0.784899, -0.003257, -0.000105, 0.917205};
  c.readout_time = kTumReadoutTime;
  if (depth_correction) c.depth_scale_correction = 1.031;
  return c;
}

PinholeCamera camera_tum_fr3() {
  PinholeCamera c;
  c.name = "tum3";
  c.fx = 535.4;
  c.fy = 539.2;
  c.cx = 320.1;
  c.cy = 247.6;
  c.readout_time = kTumReadoutTime;
  return c;
}

PinholeCamera camera_preset(const std::string& name) {
  if (name == "tum1" || name == "fr1") return camera_tum_fr1();
  if (name == "tum2" || name == "fr2") return camera_tum_fr2(false);
  if (name == "tum2-corrected") return camera_tum_fr2(true);
  if (name == "tum3" || name == "fr3") return camera_tum_fr3();
  if (name == "synthetic") {
    // fr1-like intrinsics without distortion: the default of the synthetic generator.
    PinholeCamera c = camera_tum_fr1();
    c.name = "synthetic";
    c.dist = {0, 0, 0, 0, 0};
    c.readout_time = 0.0;  // the renderer exposes every row at once
    return c;
  }
  throw ConfigError("unknown camera preset '" + name + "' (use tum1, tum2, tum2-corrected, tum3, synthetic or a file)");
}

}  // namespace cslam
