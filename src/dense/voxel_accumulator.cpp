#include "dense/voxel_accumulator.h"

#include <algorithm>
#include <stdexcept>

#include "cloud/filters.h"
#include "core/stopwatch.h"

namespace cslam {

VoxelAccumulator::VoxelAccumulator(double voxel_size, double refilter_growth)
    : voxel_(float(voxel_size)), growth_(refilter_growth) {
  if (!(voxel_size > 0)) throw std::invalid_argument("VoxelAccumulator: voxel size must be positive");
  if (!(refilter_growth > 1.0)) throw std::invalid_argument("VoxelAccumulator: refilter growth must be > 1");
}

void VoxelAccumulator::add_chunk(const ColoredCloud& chunk) {
  if (chunk.empty()) return;
  Stopwatch sw;
  ++stats_.chunks;
  stats_.raw_points += chunk.size();
  map_.append(voxel_filter(chunk, voxel_));
  stats_.peak_points = std::max(stats_.peak_points, map_.size() + chunk.size());
  if (double(map_.size()) > growth_ * double(std::max<std::size_t>(filtered_size_, 50000))) {
    map_ = voxel_filter(map_, voxel_);
    filtered_size_ = map_.size();
    ++stats_.refilters;
  }
  stats_.filter_ms += sw.ms();
}

ColoredCloud VoxelAccumulator::finish() {
  Stopwatch sw;
  ColoredCloud out = voxel_filter(map_, voxel_);
  map_ = ColoredCloud();
  filtered_size_ = 0;
  stats_.filter_ms += sw.ms();
  return out;
}

}  // namespace cslam
