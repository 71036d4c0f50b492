#pragma once
// Bounded-memory accumulation of back-projected points: each chunk of frames is voxel-filtered
// on arrival (PCL VoxelGrid) and its voxel centroids are merged into a voxel map (hash of voxel
// index -> running sums), so raw points never pile up and the merged map is never re-filtered.
// Both grids are aligned to multiples of the voxel size from the origin, so a chunk centroid
// falls in the voxel of its points. Each chunk's centroid counts once in a voxel's mean.
// Single-threaded; the reconstructor runs it on its own worker thread.
#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "cloud/point_cloud.h"

namespace cslam {

struct AccumulatorStats {
  std::size_t chunks = 0, raw_points = 0, chunk_voxels = 0, peak_points = 0;
  double filter_ms = 0;  // PCL filtering of chunks (summed over threads) + merging
};

class VoxelAccumulator {
 public:
  explicit VoxelAccumulator(double voxel_size);
  void add_chunk(const ColoredCloud& chunk) { merge(filter_chunk(chunk), chunk.size()); }
  // The two halves of add_chunk: filter_chunk is const and may run on several threads at once
  // (PCL VoxelGrid); merge must be serialised by the caller.
  ColoredCloud filter_chunk(const ColoredCloud& chunk) const;
  void merge(const ColoredCloud& filtered, std::size_t raw_points, double filter_ms = 0);
  // One point per occupied voxel (mean of the chunk centroids, mean colour); the accumulator
  // is empty afterwards.
  ColoredCloud finish();
  std::size_t voxels() const { return cells_.size(); }
  const AccumulatorStats& stats() const { return stats_; }

 private:
  struct Cell {
    Eigen::Vector3f sum{0, 0, 0};
    std::array<std::uint32_t, 3> rgb{0, 0, 0};
    std::uint32_t count = 0;
  };
  float voxel_;
  std::unordered_map<std::uint64_t, std::uint32_t> index_;  // voxel key -> cell
  std::vector<Cell> cells_;
  bool colors_ = true;
  AccumulatorStats stats_;
};

}  // namespace cslam
