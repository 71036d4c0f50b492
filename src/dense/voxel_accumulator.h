#pragma once
// Bounded-memory accumulation of back-projected points: each chunk is voxel-filtered on
// arrival and merged into the filtered map, which is re-filtered when it has grown by a factor
// since its last filtering. The voxel grid is aligned to multiples of the voxel size, so
// re-filtering keeps every point in its voxel and the final cloud has one point per voxel.
// Single-threaded; the reconstructor runs it on its own worker thread.
#include <cstddef>

#include "cloud/point_cloud.h"

namespace cslam {

struct AccumulatorStats {
  std::size_t chunks = 0, raw_points = 0, refilters = 0, peak_points = 0;
  double filter_ms = 0;
};

class VoxelAccumulator {
 public:
  VoxelAccumulator(double voxel_size, double refilter_growth);
  void add_chunk(const ColoredCloud& chunk);
  // Final filtering; the accumulator is empty afterwards.
  ColoredCloud finish();
  const AccumulatorStats& stats() const { return stats_; }

 private:
  float voxel_;
  double growth_;
  ColoredCloud map_;
  std::size_t filtered_size_ = 0;  // size of map_ right after its last filtering
  AccumulatorStats stats_;
};

}  // namespace cslam
