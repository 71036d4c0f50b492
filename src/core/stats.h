#pragma once
#include <string>
#include <vector>

namespace cslam {

// Summary of a list of errors, in the order of the paper's Table II plus n and median.
struct ErrorStats {
  int n = 0;
  double max = 0, min = 0, mean = 0, median = 0, rmse = 0, std = 0;  // std: population
};
ErrorStats compute_stats(std::vector<double> values);

// Median, min, max of a list (for timings); empty list -> zeros.
struct Summary {
  int n = 0;
  double median = 0, mean = 0, min = 0, max = 0, p95 = 0;
};
Summary summarize(std::vector<double> values);

}  // namespace cslam
