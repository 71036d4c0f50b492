#pragma once
// Spatial index over the undistorted keypoints of one frame, for radius queries (matching by
// projection during tracking, stereo/RGB-D search windows).
#include <array>
#include <vector>

#include "slam/features/orb_extractor.h"

namespace cslam {

class FeatureGrid {
 public:
  FeatureGrid() = default;
  // bounds = camera.undistorted_bounds() {min_u, max_u, min_v, max_v}. Features outside the
  // bounds are clamped into the border cells. Throws std::invalid_argument on empty bounds or cols/rows < 1.
  FeatureGrid(const OrbFeatures& features, const std::array<double, 4>& bounds, int cols = 64, int rows = 48);

  // Indices of features whose undistorted position lies within the square of half-size r around
  // (u,v) and (if min_level >= 0 / max_level >= 0) whose octave is within [min_level, max_level].
  std::vector<int> features_in_area(double u, double v, double r, int min_level = -1, int max_level = -1) const;
  // The same into `out` (cleared first), so that a search over many points reuses one buffer.
  void features_in_area(double u, double v, double r, int min_level, int max_level, std::vector<int>& out) const;

  std::size_t size() const { return entries_.size(); }

 private:
  int col_of(double u) const;
  int row_of(double v) const;

  // A feature as the queries read it, stored cell by cell (cell c holds entries
  // [cell_start_[c], cell_start_[c + 1]), in ascending index): one contiguous scan per cell row.
  struct Entry {
    double u, v;
    int level, index;
  };

  std::array<double, 4> bounds_{0, 1, 0, 1};
  int cols_ = 0, rows_ = 0;
  double inv_cell_w_ = 0, inv_cell_h_ = 0;
  std::vector<int> cell_start_;
  std::vector<Entry> entries_;
};

}  // namespace cslam
