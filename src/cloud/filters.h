#pragma once
// Point cloud filters backed by PCL (VoxelGrid, StatisticalOutlierRemoval); PCL types stay
// inside the .cpp so callers only see ColoredCloud.
#include "cloud/point_cloud.h"

namespace cslam {

// Voxel-grid filter: one point per occupied voxel (cube of side voxel_size aligned to multiples
// of voxel_size from the origin), at the centroid of its points with their mean colour.
// Large extents that would overflow PCL's 32-bit voxel index are split into voxel-aligned
// slabs first, so the result is the same. Normals are dropped. voxel_size <= 0 throws
// std::invalid_argument.
ColoredCloud voxel_filter(const ColoredCloud& cloud, float voxel_size);

struct OutlierConfig {
  int mean_k = 20;          // neighbours whose mean distance is measured
  double stddev_mul = 2.0;  // points with mean distance > mean + stddev_mul * std are removed
};
// Statistical outlier removal; returns the kept points.
ColoredCloud remove_statistical_outliers(const ColoredCloud& cloud, const OutlierConfig& config = {});

}  // namespace cslam
