#include "features/feature_grid.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace cslam {

FeatureGrid::FeatureGrid(const OrbFeatures& features, const std::array<double, 4>& bounds, int cols, int rows)
    : bounds_(bounds), cols_(cols), rows_(rows) {
  if (cols < 1 || rows < 1) throw std::invalid_argument("FeatureGrid: cols and rows must be >= 1");
  if (!(bounds[1] > bounds[0]) || !(bounds[3] > bounds[2])) throw std::invalid_argument("FeatureGrid: empty bounds");
  if (features.undistorted.size() != features.keypoints.size())
    throw std::invalid_argument("FeatureGrid: features.undistorted and keypoints differ in size");
  inv_cell_w_ = cols / (bounds[1] - bounds[0]);
  inv_cell_h_ = rows / (bounds[3] - bounds[2]);
  cells_.assign(std::size_t(cols) * rows, {});
  const std::size_t n = features.size();
  u_.resize(n);
  v_.resize(n);
  level_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    u_[i] = features.undistorted[i].x();
    v_[i] = features.undistorted[i].y();
    level_[i] = features.keypoints[i].octave;
    cells_[std::size_t(row_of(v_[i])) * cols_ + col_of(u_[i])].push_back(int(i));
  }
}

int FeatureGrid::col_of(double u) const {
  const double c = std::floor((u - bounds_[0]) * inv_cell_w_);
  return int(std::clamp(c, 0.0, double(cols_ - 1)));
}

int FeatureGrid::row_of(double v) const {
  const double r = std::floor((v - bounds_[2]) * inv_cell_h_);
  return int(std::clamp(r, 0.0, double(rows_ - 1)));
}

std::vector<int> FeatureGrid::features_in_area(double u, double v, double r, int min_level, int max_level) const {
  std::vector<int> out;
  features_in_area(u, v, r, min_level, max_level, out);
  return out;
}

void FeatureGrid::features_in_area(double u, double v, double r, int min_level, int max_level, std::vector<int>& out) const {
  out.clear();
  if (cells_.empty() || !(r >= 0) || !std::isfinite(u) || !std::isfinite(v)) return;
  // Features clamped into border cells may lie outside the bounds, so border cells are always
  // included when the square touches them; the exact test below decides.
  const int c0 = col_of(u - r), c1 = col_of(u + r), r0 = row_of(v - r), r1 = row_of(v + r);
  for (int row = r0; row <= r1; ++row) {
    for (int col = c0; col <= c1; ++col) {
      for (int i : cells_[std::size_t(row) * cols_ + col]) {
        if (std::abs(u_[i] - u) > r || std::abs(v_[i] - v) > r) continue;
        if (min_level >= 0 && level_[i] < min_level) continue;
        if (max_level >= 0 && level_[i] > max_level) continue;
        out.push_back(i);
      }
    }
  }
  std::sort(out.begin(), out.end());
}

}  // namespace cslam
