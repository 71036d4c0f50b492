#include "slam/features/feature_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>
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
  const std::size_t n = features.size(), num_cells = std::size_t(cols) * rows;
  std::vector<int> cell(n);
  cell_start_.assign(num_cells + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const double u = features.undistorted[i].x(), v = features.undistorted[i].y();
    cell[i] = row_of(v) * cols_ + col_of(u);
    ++cell_start_[std::size_t(cell[i]) + 1];
  }
  for (std::size_t c = 0; c < num_cells; ++c) cell_start_[c + 1] += cell_start_[c];
  entries_.resize(n);
  std::vector<int> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (std::size_t i = 0; i < n; ++i)
    entries_[std::size_t(fill[std::size_t(cell[i])]++)] = {features.undistorted[i].x(), features.undistorted[i].y(),
                                                           features.keypoints[i].octave, int(i)};
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

void FeatureGrid::features_in_area(double u, double v, double r, int min_level, int max_level,
                                   std::vector<int>& out) const {
  out.clear();
  if (entries_.empty() || !(r >= 0) || !std::isfinite(u) || !std::isfinite(v)) return;
  // Features clamped into border cells may lie outside the bounds, so border cells are always
  // included when the square touches them; the exact test below decides.
  const int c0 = col_of(u - r), c1 = col_of(u + r), r0 = row_of(v - r), r1 = row_of(v + r);
  const int lo = min_level >= 0 ? min_level : std::numeric_limits<int>::min();
  const int hi = max_level >= 0 ? max_level : std::numeric_limits<int>::max();
  for (int row = r0; row <= r1; ++row) {
    // The cells c0..c1 of one row are contiguous in entries_. Without branches: which entries
    // pass is as good as random (a third of the square's entries are on other levels), and a
    // mispredicted branch cost more than the test.
    const Entry* e = entries_.data() + cell_start_[std::size_t(row) * cols_ + c0];
    const Entry* end = entries_.data() + cell_start_[std::size_t(row) * cols_ + c1 + 1];
    const std::size_t n = out.size();
    out.resize(n + std::size_t(end - e));
    int* dst = out.data() + n;
    for (; e != end; ++e) {
      *dst = e->index;
      dst += int(std::abs(e->u - u) <= r) & int(std::abs(e->v - v) <= r) & int(e->level >= lo) & int(e->level <= hi);
    }
    out.resize(std::size_t(dst - out.data()));
  }
  std::sort(out.begin(), out.end());
}

}  // namespace cslam
