#include "slam/features/orb_extractor.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "slam/features/fast_corners.h"
#include "slam/features/linear_resize.h"
#include "slam/features/orb_blur.h"
#include "slam/features/orb_descriptor.h"
#include "slam/features/patch_moments.h"

namespace cslam {

namespace {

constexpr int kPatchSize = 31;

// A quadtree node: a rectangle and a range [begin, end) of the shared index array.
struct QuadNode {
  float x0, y0, x1, y1;
  int begin, end;
  int count() const { return end - begin; }
  bool splittable() const { return count() > 1 && (x1 - x0) > 1.0f && (y1 - y0) > 1.0f; }
};

// A keypoint as the quadtree reads it, stored in the node ranges themselves (partitioned in place).
struct QuadPoint {
  float x, y, response;
  int index;  // into the input keypoints
};

// Splits `n` into up to four children (only non-empty ones are appended), partitioning pts in place.
void split_node(const QuadNode& n, std::vector<QuadPoint>& pts, std::vector<QuadNode>& out) {
  const float xm = 0.5f * (n.x0 + n.x1), ym = 0.5f * (n.y0 + n.y1);
  auto first = pts.begin() + n.begin, last = pts.begin() + n.end;
  auto left = [&](const QuadPoint& p) { return p.x < xm; };
  auto top = [&](const QuadPoint& p) { return p.y < ym; };
  auto mid_x = std::partition(first, last, left);
  auto mid_l = std::partition(first, mid_x, top);
  auto mid_r = std::partition(mid_x, last, top);
  const int b = n.begin;
  auto pos = [&](std::vector<QuadPoint>::iterator it) { return int(it - pts.begin()); };
  const QuadNode children[4] = {{n.x0, n.y0, xm, ym, b, pos(mid_l)},
                                {n.x0, ym, xm, n.y1, pos(mid_l), pos(mid_x)},
                                {xm, n.y0, n.x1, ym, pos(mid_x), pos(mid_r)},
                                {xm, ym, n.x1, n.y1, pos(mid_r), n.end}};
  for (const QuadNode& c : children)
    if (c.count() > 0) out.push_back(c);
}

// Offset of a FAST corner at integer (x, y) inside its pixel: per axis, the vertex of the parabola
// through the scores of the pixel and its two neighbours (the corner is a local maximum of the
// score, so the vertex lies within half a pixel). Zero where the score does not curve down.
cv::Point2f score_peak_offset(const cv::Mat& level, int x, int y, int centre_score) {
  if (x < 4 || y < 4 || x >= level.cols - 4 || y >= level.rows - 4) return {0.f, 0.f};
  const std::array<int, 4> n = fast_neighbour_scores(level, x, y);
  const double c = centre_score, l = n[0], r = n[1], u = n[2], d = n[3];
  auto vertex = [c](double before, double after) {
    const double curvature = before - 2 * c + after;
    return curvature < 0 ? std::clamp(0.5 * (before - after) / curvature, -0.5, 0.5) : 0.0;
  };
  return {float(vertex(l, r)), float(vertex(u, d))};
}

}  // namespace

std::vector<cv::KeyPoint> distribute_quadtree(const std::vector<cv::KeyPoint>& keypoints, const cv::Rect2f& area,
                                              int budget) {
  if (budget <= 0 || keypoints.empty()) return {};
  if (int(keypoints.size()) <= budget) return keypoints;
  std::vector<QuadPoint> pts(keypoints.size());
  for (std::size_t i = 0; i < keypoints.size(); ++i)
    pts[i] = {keypoints[i].pt.x, keypoints[i].pt.y, keypoints[i].response, int(i)};

  // Initial nodes: roughly square, side by side along the longer image axis.
  std::vector<QuadNode> nodes, next;
  const int n_ini = std::max(1, int(std::lround(area.width / std::max(1.0f, area.height))));
  const float w = area.width / n_ini;
  {
    std::vector<QuadNode> roots;
    QuadNode all{area.x, area.y, area.x + area.width, area.y + area.height, 0, int(pts.size())};
    if (n_ini == 1) {
      roots.push_back(all);
    } else {
      // Partition by column.
      int begin = 0;
      for (int c = 0; c < n_ini; ++c) {
        const float x1 = c + 1 == n_ini ? area.x + area.width + 1.0f : area.x + (c + 1) * w;
        auto mid = std::partition(pts.begin() + begin, pts.end(), [&](const QuadPoint& p) { return p.x < x1; });
        const int end = int(mid - pts.begin());
        if (end > begin)
          roots.push_back(
              {area.x + c * w, area.y, std::min(x1, area.x + area.width), area.y + area.height, begin, end});
        begin = end;
      }
    }
    nodes = std::move(roots);
  }

  while (int(nodes.size()) < budget) {
    int splittable = 0;
    for (const QuadNode& n : nodes) splittable += n.splittable();
    if (splittable == 0) break;
    if (int(nodes.size()) + 3 * splittable < budget) {
      next.clear();
      for (const QuadNode& n : nodes) {
        if (n.splittable())
          split_node(n, pts, next);
        else
          next.push_back(n);
      }
      if (next.size() == nodes.size()) break;  // nothing could be separated
      nodes.swap(next);
      continue;
    }
    // Last round: split the most populated nodes first until the budget is reached.
    std::stable_sort(nodes.begin(), nodes.end(),
                     [](const QuadNode& a, const QuadNode& b) { return a.count() > b.count(); });
    next.clear();
    std::size_t i = 0;
    int total = int(nodes.size());
    for (; i < nodes.size() && total < budget; ++i) {
      if (!nodes[i].splittable()) {
        next.push_back(nodes[i]);
        continue;
      }
      const std::size_t before = next.size();
      split_node(nodes[i], pts, next);
      total += int(next.size() - before) - 1;
    }
    for (; i < nodes.size(); ++i) next.push_back(nodes[i]);
    nodes.swap(next);
    break;
  }

  std::vector<cv::KeyPoint> out;
  out.reserve(nodes.size());
  for (const QuadNode& n : nodes) {
    int best = n.begin;
    for (int k = n.begin + 1; k < n.end; ++k)
      if (pts[k].response > pts[best].response) best = k;
    out.push_back(keypoints[pts[best].index]);
  }
  if (int(out.size()) > budget) {
    std::nth_element(out.begin(), out.begin() + budget, out.end(),
                     [](const cv::KeyPoint& a, const cv::KeyPoint& b) { return a.response > b.response; });
    out.resize(budget);
  }
  return out;
}

OrbExtractor::OrbExtractor(const OrbConfig& config) : config_(config) {
  if (config.num_features < 1) throw ConfigError("OrbConfig.num_features must be >= 1");
  if (config.num_levels < 1 || config.num_levels > 16) throw ConfigError("OrbConfig.num_levels must be in [1,16]");
  if (!(config.scale_factor > 1.0) || config.scale_factor > 4.0)
    throw ConfigError("OrbConfig.scale_factor must be in (1,4]");
  if (config.ini_fast_threshold < 1 || config.min_fast_threshold < 1 ||
      config.min_fast_threshold > config.ini_fast_threshold)
    throw ConfigError("OrbConfig: need 1 <= min_fast_threshold <= ini_fast_threshold");
  if (config.edge_threshold < 19) throw ConfigError("OrbConfig.edge_threshold must be >= 19 (rotated 31x31 patch)");
  if (config.cell_size < 8) throw ConfigError("OrbConfig.cell_size must be >= 8");

  pattern_ = opencv_orb_pattern();
  linear_resize_ = opencv_linear_resize();
  const int L = config.num_levels;
  scale_factors_.resize(L);
  for (int l = 0; l < L; ++l) scale_factors_[l] = std::pow(config.scale_factor, l);
  for (double s : scale_factors_) {
    inv_scale_factors_.push_back(1.0 / s);
    level_sigma2_.push_back(s * s);
    inv_level_sigma2_.push_back(1.0 / (s * s));
  }
  // Budget per level: N * (1 - f) / (1 - f^L) * f^l with f = 1/scale_factor, remainder to the top.
  const double f = 1.0 / config.scale_factor;
  double per_level = config.num_features * (1.0 - f) / (1.0 - std::pow(f, L));
  int sum = 0;
  for (int l = 0; l + 1 < L; ++l) {
    features_per_level_.push_back(int(std::lround(per_level)));
    sum += features_per_level_.back();
    per_level *= f;
  }
  features_per_level_.push_back(std::max(0, config.num_features - sum));
}

float OrbExtractor::orientation(const cv::Mat& image, const cv::Point2f& pt) const {
  const int cx = int(std::lround(pt.x)), cy = int(std::lround(pt.y));
  const PatchMoments m = patch_moments(image.ptr<std::uint8_t>(cy) + cx, int(image.step1()));
  return cv::fastAtan2(float(m.m01), float(m.m10));  // degrees in [0,360)
}

std::vector<cv::KeyPoint> OrbExtractor::detect_level(const cv::Mat& image, int budget) const {
  const int b = config_.edge_threshold;
  const int W = image.cols, H = image.rows;
  if (budget <= 0 || W <= 2 * b + 8 || H <= 2 * b + 8) return {};
  // Per ~cell_size cell, the corners scoring at least the initial threshold are kept if the cell
  // has any, else all of its corners at the fallback threshold (the ORB-SLAM2 rule).
  // FAST runs on [b-3, W-b+3) so that corners are reported in [b, W-b).
  const cv::Rect region(b - 3, b - 3, W - 2 * b + 6, H - 2 * b + 6);
  const int inner_w = W - 2 * b, inner_h = H - 2 * b;
  const int cols = std::max(1, inner_w / config_.cell_size), rows = std::max(1, inner_h / config_.cell_size);
  const float cell_w = float(inner_w) / cols, cell_h = float(inner_h) / rows;
  auto cell_of = [&](const cv::Point2f& pt) {
    if (pt.x < b || pt.y < b || pt.x >= W - b || pt.y >= H - b) return -1;
    const int c = std::min(cols - 1, int((pt.x - b) / cell_w)), r = std::min(rows - 1, int((pt.y - b) / cell_h));
    return r * cols + c;
  };
  // One FAST pass at the fallback threshold over the whole region finds both sets: a corner's
  // score (the highest threshold at which it is detected) does not depend on the threshold, and a
  // strong corner survives the non-maximum suppression among all corners exactly when it survives
  // among the strong ones alone (a weaker neighbour never suppresses it). One pass costs less than
  // a strong pass plus fallback passes over the weak cells: FAST rejects 32-pixel blocks, not
  // pixels, and the weak cells' blocks that passed the strong test were scored twice.
  std::vector<cv::KeyPoint> found;
  detect_fast_corners(image(region), config_.min_fast_threshold, found);  // <= ini_fast_threshold (validated)
  std::vector<int> cell(found.size());
  std::vector<std::uint8_t> strong(std::size_t(cols) * rows, 0);
  for (std::size_t i = 0; i < found.size(); ++i) {
    cv::KeyPoint& kp = found[i];
    kp.pt.x += float(region.x);
    kp.pt.y += float(region.y);
    cell[i] = cell_of(kp.pt);
    if (cell[i] >= 0 && kp.response >= float(config_.ini_fast_threshold)) strong[std::size_t(cell[i])] = 1;
  }
  std::vector<cv::KeyPoint> kps;
  kps.reserve(found.size());
  for (std::size_t i = 0; i < found.size(); ++i)
    if (cell[i] >= 0 && (!strong[std::size_t(cell[i])] || found[i].response >= float(config_.ini_fast_threshold)))
      kps.push_back(found[i]);
  return distribute_quadtree(kps, cv::Rect2f(float(b), float(b), float(inner_w), float(inner_h)), budget);
}

OrbFeatures OrbExtractor::extract(const cv::Mat& input, const PinholeCamera* camera) const {
  OrbFeatures out;
  if (input.empty()) return out;
  cv::Mat gray;
  if (input.type() == CV_8UC1)
    gray = input;
  else if (input.type() == CV_8UC3)
    cv::cvtColor(input, gray, cv::COLOR_BGR2GRAY);
  else
    throw std::invalid_argument("OrbExtractor::extract: image must be CV_8UC1 or CV_8UC3");

  const int L = config_.num_levels;
  // Descriptors: OpenCV's bits, computed here (orb_descriptor.h) unless the pattern could not be
  // read from OpenCV; then by cv::ORB::compute.
  cv::Ptr<cv::ORB> orb;
  if (!pattern_)
    orb = cv::ORB::create(config_.num_features, float(config_.scale_factor), 1, config_.edge_threshold, 0, 2,
                          cv::ORB::FAST_SCORE, kPatchSize, config_.ini_fast_threshold);
  cv::Mat level = gray;
  int carry = 0;  // budget a level could not use is handed to the next one
  std::vector<cv::KeyPoint> kps;
  cv::Mat desc, blurred;
  std::vector<Descriptor> level_descriptors;
  for (int l = 0; l < L; ++l) {
    if (l > 0) {
      const cv::Size size(int(std::lround(gray.cols * inv_scale_factors_[l])),
                          int(std::lround(gray.rows * inv_scale_factors_[l])));
      if (size.width <= 2 * config_.edge_threshold + 8 || size.height <= 2 * config_.edge_threshold + 8) break;
      cv::Mat smaller;
      if (linear_resize_)
        resize_linear(level, smaller, size, *linear_resize_);
      else
        cv::resize(level, smaller, size, 0, 0, cv::INTER_LINEAR);
      level = smaller;
    }
    const int budget = features_per_level_[l] + carry;
    kps = detect_level(level, budget);
    carry = budget - int(kps.size());
    if (kps.empty()) continue;
    for (std::size_t i = 0; i < kps.size(); ++i) {
      kps[i].angle = orientation(level, kps[i].pt);
      kps[i].octave = 0;
      kps[i].size = float(kPatchSize);
      kps[i].class_id = int(i);
    }
    const std::size_t n_before = kps.size();
    std::vector<cv::KeyPoint> detected = kps;
    if (pattern_) {
      // detect_level keeps keypoints at >= edge_threshold from the border: cv::ORB::compute's
      // border filter would drop none of them.
      level_descriptors.clear();
      orb_blur(level, blurred);
      compute_orb_descriptors(blurred, kps, *pattern_, level_descriptors);
      desc = cv::Mat(int(level_descriptors.size()), 32, CV_8UC1, level_descriptors.data());
    } else {
      orb->compute(level, kps, desc);
    }
    // OpenCV may drop keypoints near the border; class_id maps the survivors back.
    const double s = scale_factors_[l];
    // A level's pixel to level 0: cv::resize aligns pixel centres, and the level's size was
    // rounded, so x0 + 0.5 = (x + 0.5) * W0 / W (per axis), not x * s.
    const double rx = double(gray.cols) / level.cols, ry = double(gray.rows) / level.rows;
    for (std::size_t i = 0; i < kps.size() && int(i) < desc.rows; ++i) {
      const int id = kps[i].class_id;
      if (id < 0 || std::size_t(id) >= n_before) continue;
      cv::KeyPoint kp = detected[id];
      if (config_.subpixel && kp.response >= config_.ini_fast_threshold)
        kp.pt += score_peak_offset(level, int(kp.pt.x), int(kp.pt.y), int(kp.response));
      kp.pt.x = float((kp.pt.x + 0.5) * rx - 0.5);
      kp.pt.y = float((kp.pt.y + 0.5) * ry - 0.5);
      kp.size = float(kPatchSize * s);
      kp.octave = l;
      kp.class_id = -1;
      out.keypoints.push_back(kp);
      Descriptor d;
      std::memcpy(d.data(), desc.ptr<std::uint8_t>(int(i)), 32);
      out.descriptors.push_back(d);
    }
  }

  out.undistorted.reserve(out.keypoints.size());
  for (const cv::KeyPoint& kp : out.keypoints) out.undistorted.emplace_back(kp.pt.x, kp.pt.y);
  if (camera && camera->has_distortion()) camera->undistort_pixels(out.undistorted);
  return out;
}

}  // namespace cslam
