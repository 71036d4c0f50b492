#include "map/frame_data.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "bow/vocabulary.h"

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
bool depth_is_smooth(const cv::Mat& depth_raw, int x, int y, double d, const PinholeCamera& camera, const RgbdParams& rgbd) {
  const int r = rgbd.depth_edge_radius;
  if (r <= 0 || d <= 0) return true;
  double lo = d, hi = d;
  for (int yy = std::max(0, y - r); yy <= std::min(depth_raw.rows - 1, y + r); ++yy) {
    const auto* row = depth_raw.ptr<std::uint16_t>(yy);
    for (int xx = std::max(0, x - r); xx <= std::min(depth_raw.cols - 1, x + r); ++xx) {
      if (row[xx] == 0) return false;
      const double dd = camera.depth_from_raw(row[xx]);
      lo = std::min(lo, dd);
      hi = std::max(hi, dd);
    }
  }
  return hi - lo <= rgbd.depth_edge_ratio * d;
}
}  // namespace

std::shared_ptr<const FrameData> make_frame_data(FrameId id, double timestamp, const cv::Mat& bgr, const cv::Mat& depth_raw,
                                                 const PinholeCamera& camera, const RgbdParams& rgbd,
                                                 const OrbExtractor& extractor,
                                                 const std::shared_ptr<const ScalePyramid>& pyramid,
                                                 const Vocabulary& vocabulary, int bow_levels_up) {
  auto f = std::make_shared<FrameData>();
  f->id = id;
  f->timestamp = timestamp;
  f->camera = camera;
  f->rgbd = rgbd;
  f->pyramid = pyramid;
  cv::Mat gray;
  if (bgr.channels() == 3) cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  else gray = bgr;
  f->features = extractor.extract(gray, &camera);
  const size_t n = f->features.size();
  f->depth.assign(n, -1.f);
  f->u_right.assign(n, -1.f);
  f->colors.assign(n, cv::Vec3b(0, 0, 0));
  for (size_t i = 0; i < n; ++i) {
    const cv::Point2f& pt = f->features.keypoints[i].pt;
    const int x = int(std::lround(pt.x)), y = int(std::lround(pt.y));
    if (x < 0 || y < 0 || x >= depth_raw.cols || y >= depth_raw.rows) continue;
    if (bgr.channels() == 3) f->colors[i] = bgr.at<cv::Vec3b>(y, x);
    const double d = camera.depth_from_raw(depth_raw.at<std::uint16_t>(y, x));
    if (!depth_is_smooth(depth_raw, x, y, d, camera, rgbd)) continue;  // occlusion boundary: monocular keypoint
    if (d > rgbd.min_depth && d < rgbd.max_depth) {
      f->depth[i] = float(d);
      f->u_right[i] = float(f->features.undistorted[i].x() - rgbd.bf / d);
    }
  }
  f->bounds = camera.undistorted_bounds();
  f->grid = FeatureGrid(f->features, f->bounds);
  if (!vocabulary.empty()) vocabulary.transform(f->features.descriptors, f->bow, f->feature_vector, bow_levels_up);
  return f;
}

}  // namespace cslam
