#include "core/stats.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace cslam {

namespace {
double median_of_sorted(const std::vector<double>& v) {
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}
}  // namespace

ErrorStats compute_stats(std::vector<double> values) {
  ErrorStats s;
  s.n = int(values.size());
  if (values.empty()) return s;
  std::sort(values.begin(), values.end());
  s.min = values.front();
  s.max = values.back();
  s.median = median_of_sorted(values);
  double sum = 0, sq = 0;
  for (double v : values) {
    sum += v;
    sq += v * v;
  }
  s.mean = sum / s.n;
  s.rmse = std::sqrt(sq / s.n);
  double var = 0;
  for (double v : values) var += (v - s.mean) * (v - s.mean);
  s.std = std::sqrt(var / s.n);
  return s;
}

Summary summarize(std::vector<double> values) {
  Summary s;
  s.n = int(values.size());
  if (values.empty()) return s;
  std::sort(values.begin(), values.end());
  s.min = values.front();
  s.max = values.back();
  s.median = median_of_sorted(values);
  s.mean = std::accumulate(values.begin(), values.end(), 0.0) / s.n;
  s.p95 = values[std::min(values.size() - 1, size_t(std::ceil(0.95 * values.size())) - 1)];
  return s;
}

}  // namespace cslam
