#pragma once
// ORB features in the ORB-SLAM2 manner: an 8-level pyramid (factor 1.2), FAST with an initial
// threshold and a lower fallback threshold per 30-pixel cell, keypoints spread evenly over each
// level with a quadtree and a per-level budget following a geometric series, intensity-centroid
// orientation (circular patch of radius 15) and 256-bit rotated BRIEF descriptors, bit for bit
// those of OpenCV's ORB on the Gaussian-blurred level (7x7, sigma 2) with our keypoints and angles
// (orb_descriptor.h).
#include <array>
#include <cstddef>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "slam/features/descriptor.h"
#include "geometry/camera.h"

namespace cslam {

struct OrbPattern;    // orb_descriptor.h
struct LinearResize;  // linear_resize.h

struct OrbConfig {
  int num_features = 1000;
  double scale_factor = 1.2;
  int num_levels = 8;
  int ini_fast_threshold = 20;
  int min_fast_threshold = 7;
  // Keypoints closer than this to a level's border are not detected (room for the rotated patch).
  int edge_threshold = 19;
  // FAST cell size (pixels) for the fallback threshold.
  int cell_size = 30;
  // Strong corners (FAST score >= ini_fast_threshold) are placed inside their pixel at the vertex
  // of the parabola through the FAST scores of the pixel and its neighbours, per axis; weaker
  // ones, whose scores are dominated by image noise, keep the pixel centre.
  bool subpixel = true;
};

struct OrbFeatures {
  std::vector<cv::KeyPoint>
      keypoints;  // level-0 pixel coords as detected (distorted); .octave = pyramid level; .angle in degrees [0,360)
  std::vector<Eigen::Vector2d> undistorted;  // undistorted pixel coords (== keypoints if no camera / no distortion)
  std::vector<Descriptor> descriptors;
  std::size_t size() const { return keypoints.size(); }
  bool empty() const { return keypoints.empty(); }
};

class OrbExtractor {
 public:
  // Throws ConfigError on impossible values (non-positive counts, scale factor <= 1, thresholds).
  // The first one made in a process reads the descriptor pattern and cv::resize's rounding from
  // OpenCV (orb_descriptor.h, linear_resize.h; ~10 ms).
  explicit OrbExtractor(const OrbConfig& config = {});

  // gray: CV_8UC1 (CV_8UC3 BGR is converted). Thread-safe (const; no mutable scratch).
  // Empty/black image -> 0 features, no throw. Other image types throw std::invalid_argument.
  OrbFeatures extract(const cv::Mat& gray, const PinholeCamera* camera = nullptr) const;

  const OrbConfig& config() const { return config_; }
  const std::vector<double>& scale_factors() const { return scale_factors_; }  // scale_factor^l
  const std::vector<double>& inv_scale_factors() const { return inv_scale_factors_; }
  const std::vector<double>& level_sigma2() const { return level_sigma2_; }  // scale_factors()[l]^2
  const std::vector<double>& inv_level_sigma2() const { return inv_level_sigma2_; }
  // Keypoint budget of each level (geometric series summing to num_features).
  const std::vector<int>& features_per_level() const { return features_per_level_; }

 private:
  std::vector<cv::KeyPoint> detect_level(const cv::Mat& image, int budget) const;
  float orientation(const cv::Mat& image, const cv::Point2f& pt) const;

  OrbConfig config_;
  const OrbPattern* pattern_ = nullptr;          // OpenCV's descriptor pattern (orb_descriptor.h); null: cv::ORB
  const LinearResize* linear_resize_ = nullptr;  // cv::resize's rounding (linear_resize.h); null: cv::resize
  std::vector<double> scale_factors_, inv_scale_factors_, level_sigma2_, inv_level_sigma2_;
  std::vector<int> features_per_level_;
};

// Keeps at most `budget` keypoints spread over `area` with a quadtree: nodes holding more than
// one keypoint are split into four until there are `budget` nodes (or nothing can be split),
// then the strongest keypoint of each node is kept. Exposed for tests.
std::vector<cv::KeyPoint> distribute_quadtree(const std::vector<cv::KeyPoint>& keypoints, const cv::Rect2f& area,
                                              int budget);

}  // namespace cslam
