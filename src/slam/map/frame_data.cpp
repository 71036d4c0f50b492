#include "slam/map/frame_data.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <opencv2/imgproc.hpp>

#include "slam/bow/vocabulary.h"
#include "slam/map/rolling_shutter.h"

namespace cslam {

std::shared_ptr<const ScalePyramid> ScalePyramid::from(const OrbExtractor& extractor) {
  auto p = std::make_shared<ScalePyramid>();
  p->num_levels = extractor.config().num_levels;
  p->scale_factor = extractor.config().scale_factor;
  p->log_scale_factor = std::log(p->scale_factor);
  p->scale = extractor.scale_factors();
  p->sigma2 = extractor.level_sigma2();
  p->inv_sigma2 = extractor.inv_level_sigma2();
  return p;
}

int ScalePyramid::predict_level(double distance, double max_distance) const {
  const double ratio = max_distance / distance;
  int level = int(std::ceil(std::log(ratio) / log_scale_factor));
  if (level < 0) level = 0;
  if (level >= num_levels) level = num_levels - 1;
  return level;
}

namespace {
// The depth image is captured at another instant than the colour image (fr1: 12 ms apart on
// median) and registered to it only approximately, so at an occlusion boundary the depth looked up
// at a keypoint may belong to the other surface. Depth is used only where the whole window around
// the keypoint is measured and spans less than depth_edge_ratio of it.
bool depth_is_smooth(const cv::Mat& depth_raw, int x, int y, double d, const PinholeCamera& camera,
                     const RgbdParams& rgbd) {
  const int r = rgbd.depth_edge_radius;
  if (r <= 0 || d <= 0) return true;
  // The window's extremes in raw units: depth_from_raw is non-decreasing, so they convert to the
  // extremes in metres (the window is never empty: it holds (x, y)).
  std::uint16_t lo_raw = UINT16_MAX, hi_raw = 0;
  const int x0 = std::max(0, x - r), x1 = std::min(depth_raw.cols - 1, x + r);
  for (int yy = std::max(0, y - r); yy <= std::min(depth_raw.rows - 1, y + r); ++yy) {
    const auto* row = depth_raw.ptr<std::uint16_t>(yy);
    for (int xx = x0; xx <= x1; ++xx) {
      lo_raw = std::min(lo_raw, row[xx]);
      hi_raw = std::max(hi_raw, row[xx]);
    }
  }
  if (lo_raw == 0) return false;
  const double lo = std::min(d, camera.depth_from_raw(lo_raw)), hi = std::max(d, camera.depth_from_raw(hi_raw));
  return hi - lo <= rgbd.depth_edge_ratio * d;
}
}  // namespace

double depth_at_keypoint(const cv::Mat& depth_raw, const Eigen::Vector2d& distorted, const Eigen::Vector2d& undistorted,
                         const PinholeCamera& camera, const RgbdParams& rgbd,
                         const std::optional<SE3>& T_depthcam_cam) {
  // Raw depth at a distorted pixel, 0 if outside, missing, out of range or not smooth around it.
  auto read = [&](const Eigen::Vector2d& px) {
    const int x = int(std::lround(px.x())), y = int(std::lround(px.y()));
    if (x < 0 || y < 0 || x >= depth_raw.cols || y >= depth_raw.rows) return 0.0;
    const double d = camera.depth_from_raw(depth_raw.at<std::uint16_t>(y, x));
    if (!(d > rgbd.min_depth && d < rgbd.max_depth)) return 0.0;
    return depth_is_smooth(depth_raw, x, y, d, camera, rgbd) ? d : 0.0;
  };
  if (!T_depthcam_cam || !rgbd.depth_time_compensation) return read(distorted);
  // The point at depth z on the keypoint's ray lies at X_d(z) = R ray z + t in the depth camera,
  // which measures X_d.z at the pixel X_d projects to. Solve for z by fixed-point iteration,
  // starting from the point at infinity (the rotation alone moves the pixel); the translation
  // over one inter-frame gap shifts the pixel by a few pixels at most, so two steps settle it.
  const Eigen::Matrix3d R = T_depthcam_cam->R();
  const Eigen::Vector3d& t = T_depthcam_cam->translation();
  const Eigen::Vector3d ray((undistorted.x() - camera.cx) / camera.fx, (undistorted.y() - camera.cy) / camera.fy, 1.0);
  const Eigen::Vector3d r = R * ray;
  if (r.z() <= 1e-6) return 0.0;
  auto to_pixel = [&](const Eigen::Vector3d& X_d) { return camera.distort_pixel(camera.project(X_d)); };
  double z_d = read(to_pixel(r));
  double z = 0;
  for (int iter = 0; iter < 2 && z_d > 0; ++iter) {
    z = (z_d - t.z()) / r.z();
    if (z <= 0) return 0.0;
    const Eigen::Vector3d X_d = r * z + t;
    if (X_d.z() <= 1e-6) return 0.0;
    z_d = read(to_pixel(X_d));
  }
  if (z_d <= 0) return 0.0;
  z = (z_d - t.z()) / r.z();
  return z > rgbd.min_depth && z < rgbd.max_depth ? z : 0.0;
}

std::shared_ptr<const FrameData> make_frame_data(
    FrameId id, double timestamp, const cv::Mat& bgr, const cv::Mat& depth_raw, const PinholeCamera& camera,
    const RgbdParams& rgbd, const OrbExtractor& extractor, const std::shared_ptr<const ScalePyramid>& pyramid,
    const std::shared_ptr<const Vocabulary>& vocabulary, int bow_levels_up, const std::optional<SE3>& T_depthcam_cam,
    const std::optional<SE3>& T_lastrow_cam, bool keyframe_depth, const cv::Mat& gray_in) {
  auto f = std::make_shared<FrameData>();
  f->id = id;
  f->timestamp = timestamp;
  f->camera = camera;
  f->rgbd = rgbd;
  f->pyramid = pyramid;
  cv::Mat gray = gray_in;  // the caller's grey image of `bgr` if it has one
  if (gray.empty() && bgr.channels() == 3)
    cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  else if (gray.empty())
    gray = bgr;
  f->features = extractor.extract(gray, &camera);
  const size_t n = f->features.size();
  f->keyframe_depth = keyframe_depth && !depth_raw.empty();
  f->depth.assign(n, -1.f);
  f->u_right.assign(n, -1.f);
  f->colors.assign(n, cv::Vec3b(0, 0, 0));
  for (size_t i = 0; i < n; ++i) {
    const cv::Point2f& pt = f->features.keypoints[i].pt;
    const int x = int(std::lround(pt.x)), y = int(std::lround(pt.y));
    if (x < 0 || y < 0 || x >= bgr.cols || y >= bgr.rows) continue;
    if (bgr.channels() == 3) f->colors[i] = bgr.at<cv::Vec3b>(y, x);
    const Eigen::Vector2d& und = f->features.undistorted[i];
    const double d = depth_at_keypoint(depth_raw, Eigen::Vector2d(pt.x, pt.y), und, camera, rgbd, T_depthcam_cam);
    if (d > 0) {  // else: missing, or an occlusion boundary: a monocular keypoint
      f->depth[i] = float(d);
      f->u_right[i] = float(und.x() - rgbd.bf / d);
    }
  }
  // Rolling shutter: the keypoints as a global-shutter camera at the middle row's instant would
  // have seen them (map/rolling_shutter.h).
  if (T_lastrow_cam) compensate_rolling_shutter(camera, rgbd.bf, *T_lastrow_cam, f->features, f->depth, f->u_right);
  f->bounds = camera.undistorted_bounds();
  f->grid = FeatureGrid(f->features, f->bounds);
  if (vocabulary && !vocabulary->empty()) f->pending_bow = {vocabulary, bow_levels_up};
  return f;
}

std::shared_ptr<const FrameData> with_bow(std::shared_ptr<const FrameData> data) {
  if (!data || !data->pending_bow.vocabulary) return data;
  auto f = std::make_shared<FrameData>(*data);
  f->pending_bow.vocabulary->transform(f->features.descriptors, f->bow, f->feature_vector, f->pending_bow.levels_up);
  f->pending_bow = {};
  return f;
}

}  // namespace cslam
