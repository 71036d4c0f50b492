#include "navmap/up_floor.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "navmap/voxel_walk.h"

namespace cslam {

UpEstimate estimate_up(const std::vector<SE3>& T_world_cams, const Eigen::Vector3d& default_up) {
  if (!default_up.allFinite() || default_up.norm() < 1e-9)
    throw ConfigError("navmap: default_up must be a finite non-zero vector");
  UpEstimate out;
  out.up = default_up.normalized();
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const SE3& T : T_world_cams) {
    if (!T.is_finite()) {
      ++out.cameras_skipped;
      continue;
    }
    sum += T.R().col(1);
    ++out.cameras_used;
  }
  if (out.cameras_used == 0) return out;
  const Eigen::Vector3d mean = sum / double(out.cameras_used);
  if (mean.norm() < 0.5) return out;
  out.up = -mean.normalized();
  out.from_cameras = true;
  return out;
}

std::optional<double> floor_from_heights(std::vector<double> h, double bin, double min_share,
                                         std::size_t* peak_samples) {
  h.erase(std::remove_if(h.begin(), h.end(), [](double x) { return !std::isfinite(x); }), h.end());
  if (h.empty()) return std::nullopt;
  std::sort(h.begin(), h.end());
  const double w = 3 * bin;
  const std::size_t need = std::max<std::size_t>(1, std::size_t(std::ceil(min_share * double(h.size()))));
  // Window [h[i], h[i] + w): count = j - i with j the first sample at or beyond h[i] + w.
  std::size_t j = 0, first = h.size();
  for (std::size_t i = 0; i < h.size(); ++i) {
    j = std::max(j, i);
    while (j < h.size() && h[j] < h[i] + w) ++j;
    if (j - i >= need) {
      first = i;
      break;
    }
  }
  if (first == h.size()) return std::nullopt;
  // The densest window starting within one window of the first qualifying one.
  std::size_t best_i = first, best_n = 0;
  j = first;
  for (std::size_t i = first; i < h.size() && h[i] < h[first] + w; ++i) {
    while (j < h.size() && h[j] < h[i] + w) ++j;
    if (j - i > best_n) best_n = j - i, best_i = i;
  }
  if (peak_samples) *peak_samples = best_n;
  return h[best_i + best_n / 2];  // median of the window's samples (sorted)
}

FloorEstimate estimate_floor(const SubmapViews& views, const Eigen::Vector3d& up_in, const NavMapConfig& config,
                             const std::vector<SE3>& T_world_cams) {
  if (!up_in.allFinite() || up_in.norm() < 1e-9) throw ConfigError("navmap: up must be a finite non-zero vector");
  const Eigen::Vector3d up = up_in.normalized();
  double ceiling = std::numeric_limits<double>::infinity();
  std::vector<double> cam_heights;
  for (const SE3& T : T_world_cams)
    if (T.is_finite()) cam_heights.push_back(up.dot(T.translation()));
  if (!cam_heights.empty()) {
    std::nth_element(cam_heights.begin(), cam_heights.begin() + cam_heights.size() / 2, cam_heights.end());
    ceiling = cam_heights[cam_heights.size() / 2];
  }
  FloorEstimate out;
  std::vector<double> heights;
  for (const SubmapView& v : views) {
    if (!usable(v)) continue;
    for_each_upward_crossing(v, up, config.min_voxel_weight, [&](const Eigen::Vector3d& p) {
      const double s = up.dot(p);
      if (s < ceiling) heights.push_back(s);
    });
  }
  out.samples = heights.size();
  if (auto f = floor_from_heights(std::move(heights), config.floor_bin, config.floor_min_share, &out.peak_samples)) {
    out.height = *f;
    out.found = true;
    out.rule = "peak";
    return out;
  }
  std::vector<double> surface;
  for (const SubmapView& v : views) {
    if (!usable(v)) continue;
    for_each_world_voxel(v, config.min_voxel_weight, [&](const Eigen::Vector3d& p, double d, const TsdfVoxel&) {
      if (d <= 0) surface.push_back(up.dot(p));
    });
  }
  out.samples = surface.size();
  out.peak_samples = 0;
  if (surface.empty()) {
    out.rule = "none";
    return out;
  }
  const std::size_t k = std::min(surface.size() - 1, std::size_t(config.floor_percentile * double(surface.size())));
  std::nth_element(surface.begin(), surface.begin() + std::ptrdiff_t(k), surface.end());
  out.height = surface[k];
  out.found = true;
  out.rule = "percentile";
  return out;
}

}  // namespace cslam
