#pragma once
// Cloud-to-cloud accuracy metrics (the paper's Table III): nearest-neighbour distances with a
// KD-tree (PCL KdTreeFLANN), one-sided and symmetric Hausdorff distance, mean/median/95th
// percentile C2C distances, completeness, and CloudCompare-style bounding-box matching.
#include <vector>

#include <Eigen/Core>

#include "cloud/point_cloud.h"

namespace cslam {

// For every query point, the Euclidean distance to its nearest target point.
// Throws std::invalid_argument if targets is empty. threads >= 1 split the queries.
std::vector<float> nearest_distances(const std::vector<Eigen::Vector3f>& queries,
                                     const std::vector<Eigen::Vector3f>& targets, int threads = 2);

struct DistanceStats {
  int n = 0;
  double mean = 0, median = 0, p95 = 0, max = 0, rmse = 0;  // max is the one-sided Hausdorff distance
};
DistanceStats distance_stats(std::vector<float> distances);

// Bounding-box matching as CloudCompare's "match bounding-box centers" + scale: TEST is
// translated so the axis-aligned bbox centres coincide and scaled about that centre so the
// bbox diagonals are equal: p' = center_ref + scale * (p - center_test).
struct BboxMatch {
  double scale = 1.0;
  Eigen::Vector3f center_ref{0, 0, 0}, center_test{0, 0, 0};
  Eigen::Vector3f apply(const Eigen::Vector3f& p) const { return center_ref + float(scale) * (p - center_test); }
};
BboxMatch compute_bbox_match(const std::vector<Eigen::Vector3f>& ref, const std::vector<Eigen::Vector3f>& test);

struct CloudCompareConfig {
  bool match_bbox = false;
  std::vector<double> completeness_thresholds{0.02, 0.05};  // metres
  int threads = 2;
};

struct CloudComparison {
  std::size_t ref_points = 0, test_points = 0;
  DistanceStats test_to_ref;  // C2C distances of TEST points to REF (accuracy, CloudCompare's default)
  DistanceStats ref_to_test;  // distances of REF points to TEST (used for completeness)
  double hausdorff_test_to_ref = 0, hausdorff_ref_to_test = 0, hausdorff_symmetric = 0;
  std::vector<std::pair<double, double>> completeness;  // (threshold m, share of REF points within it)
  bool bbox_matched = false;
  BboxMatch bbox;
};

// Throws std::invalid_argument if either cloud is empty.
CloudComparison compare_clouds(const std::vector<Eigen::Vector3f>& ref, const std::vector<Eigen::Vector3f>& test,
                               const CloudCompareConfig& config = {});

}  // namespace cslam
