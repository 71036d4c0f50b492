#include "slam/tracking/frame_flow.h"

#include <cmath>

#include <opencv2/video/tracking.hpp>

#include "slam/bow/vocabulary.h"
#include "core/error.h"
#include "slam/map/rolling_shutter.h"

namespace cslam {

const char* to_string(FlowMode m) {
  switch (m) {
    case FlowMode::kOff:
      return "off";
    case FlowMode::kUnderLoad:
      return "under-load";
    case FlowMode::kAlways:
      return "always";
  }
  return "unknown";
}

FlowMode parse_flow_mode(const std::string& s) {
  for (FlowMode m : {FlowMode::kOff, FlowMode::kUnderLoad, FlowMode::kAlways})
    if (s == to_string(m)) return m;
  throw ConfigError("flow mode '" + s + "': expected off, under-load or always");
}

void FlowConfig::validate() const {
  if (!(max_patch_error > 0) || window < 3 || window % 2 == 0 || levels < 0 || levels > 6 || iterations < 1 ||
      !(epsilon > 0) || max_run < 1 || max_run_overloaded < max_run || max_seeds < 1 || min_inliers < 3 ||
      !(calibration_quantile >= 0 && calibration_quantile <= 1) || calibration_window < 1 || calibration_min < 1 ||
      calibration_min > calibration_window)
    throw ConfigError(
        "flow: window odd >= 3, levels 0..6, iterations >= 1, epsilon > 0, max_run >= 1, max_run_overloaded >= "
        "max_run, max_seeds >= 1, min_inliers >= 3, "
        "max_patch_error > 0, calibration quantile in [0, 1], 1 <= calibration_min <= calibration_window");
}

FlowPyramid build_flow_pyramid(const cv::Mat& gray, const FlowConfig& config) {
  FlowPyramid p;
  cv::buildOpticalFlowPyramid(gray, p.levels, cv::Size(config.window, config.window), config.levels,
                              /*withDerivatives=*/true);
  return p;
}

namespace {

// Lucas-Kanade from `from` to `to`, starting at `guess`; status per point.
std::vector<unsigned char> flow(const FlowPyramid& from, const FlowPyramid& to, const std::vector<cv::Point2f>& pts,
                                std::vector<cv::Point2f>& guess, const FlowConfig& config) {
  std::vector<unsigned char> status;
  std::vector<float> err;  // mean absolute grey-level difference over the window, at the end
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, config.iterations, config.epsilon);
  cv::calcOpticalFlowPyrLK(from.levels, to.levels, pts, guess, status, err, cv::Size(config.window, config.window),
                           config.levels, criteria, cv::OPTFLOW_USE_INITIAL_FLOW);
  for (std::size_t k = 0; k < status.size(); ++k)
    if (!(err[k] <= config.max_patch_error)) status[k] = 0;  // the patch does not look alike (occluded, blurred, dark)
  return status;
}
}  // namespace

FlowFrame make_flow_frame(FrameId id, double timestamp, const cv::Mat& bgr, const cv::Mat& depth_raw,
                          const FrameData& previous, const FlowPyramid& previous_pyramid, const FlowPyramid& pyramid,
                          const FlowSeeds& seeds, const FlowConfig& config,
                          const std::shared_ptr<const Vocabulary>& vocabulary, int bow_levels_up,
                          const std::optional<SE3>& T_depthcam_cam, const std::optional<SE3>& T_lastrow_cam,
                          bool keyframe_depth) {
  std::vector<cv::Point2f> start, found = seeds.predicted;
  start.reserve(seeds.index.size());
  for (int i : seeds.index) start.push_back(previous.features.keypoints[std::size_t(i)].pt);
  const std::vector<unsigned char> ok =
      start.empty() ? std::vector<unsigned char>{} : flow(previous_pyramid, pyramid, start, found, config);
  const PinholeCamera& camera = previous.camera;
  const RgbdParams& rgbd = previous.rgbd;
  auto f = std::make_shared<FrameData>();
  f->id = id;
  f->timestamp = timestamp;
  f->camera = camera;
  f->rgbd = rgbd;
  f->pyramid = previous.pyramid;
  f->keyframe_depth = keyframe_depth && !depth_raw.empty();
  f->bounds = camera.undistorted_bounds();
  // The tracks that held, undistorted in one call.
  std::vector<std::size_t> kept;
  std::vector<Eigen::Vector2d> undistorted;
  for (std::size_t k = 0; k < ok.size(); ++k) {
    const cv::Point2f& pt = found[k];
    if (!ok[k] || !std::isfinite(pt.x) || !std::isfinite(pt.y)) continue;
    const int x = int(std::lround(pt.x)), y = int(std::lround(pt.y));
    if (x < 0 || y < 0 || x >= bgr.cols || y >= bgr.rows) continue;
    kept.push_back(k);
    undistorted.emplace_back(pt.x, pt.y);
  }
  camera.undistort_pixels(undistorted);
  FlowFrame out;
  for (std::size_t n = 0; n < kept.size(); ++n) {
    const std::size_t k = kept[n];
    const cv::Point2f& pt = found[k];
    const int x = int(std::lround(pt.x)), y = int(std::lround(pt.y));
    const std::size_t i = std::size_t(seeds.index[k]);
    cv::KeyPoint kp = previous.features.keypoints[i];
    kp.pt = pt;
    const Eigen::Vector2d& und = undistorted[n];
    if (!f->in_bounds(und.x(), und.y())) continue;
    f->features.keypoints.push_back(kp);
    f->features.undistorted.push_back(und);
    f->features.descriptors.push_back(previous.features.descriptors[i]);
    const double d = depth_at_keypoint(depth_raw, Eigen::Vector2d(pt.x, pt.y), und, camera, rgbd, T_depthcam_cam);
    f->depth.push_back(d > 0 ? float(d) : -1.f);
    f->u_right.push_back(d > 0 ? float(und.x() - rgbd.bf / d) : -1.f);
    f->colors.push_back(bgr.channels() == 3 ? bgr.at<cv::Vec3b>(y, x) : cv::Vec3b(0, 0, 0));
    out.previous_index.push_back(int(i));
  }
  if (T_lastrow_cam) compensate_rolling_shutter(camera, rgbd.bf, *T_lastrow_cam, f->features, f->depth, f->u_right);
  f->grid = FeatureGrid(f->features, f->bounds);
  if (vocabulary && !vocabulary->empty()) f->pending_bow = {vocabulary, bow_levels_up};
  out.data = std::move(f);
  return out;
}

}  // namespace cslam
