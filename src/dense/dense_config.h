#pragma once
// Configuration of dense reconstruction as plain structs with defaults.
#include "cloud/filters.h"

namespace cslam {

// TSDF fusion into a voxel-hashed volume (blocks of 8^3 voxels) and marching-cubes meshing.
struct TsdfConfig {
  float voxel_size = 0.01f;  // metres
  float truncation = 0.04f;  // signed-distance truncation (metres), a few voxels
  float max_weight = 64.0f;  // running-average weight cap (lets the model adapt)
  int stride = 2;            // pixel stride when finding the blocks a frame touches
  int every = 1;             // integrate every n-th used frame (1 = all)
  int threads = 2;           // threads updating blocks
};

struct DenseConfig {
  double min_depth = 0.3, max_depth = 4.0;  // metres; depth outside is ignored
  int stride = 2;                           // back-project every stride-th pixel in u and v
  double voxel_size = 0.01;                 // voxel-grid filter leaf (metres)
  int chunk_frames = 30;                    // frames back-projected before the chunk is filtered
  bool remove_outliers = false;             // statistical outlier removal on the final cloud
  OutlierConfig outliers;
  int threads = 2;             // >= 2: filtering (and image loading) run beside back-projection
  double max_time_gap = 0.02;  // pose <-> image association (s)
  // A depth image taken at another instant than its colour image (TUM: depth.txt's stamps) is
  // placed with the trajectory interpolated at its own time (neighbour poses <= 0.1 s apart;
  // else at the colour image's pose); false: every depth image at its colour image's pose.
  bool depth_time_compensation = true;
  bool build_mesh = false;  // TSDF fusion + marching cubes
  TsdfConfig tsdf;

  // Throws ConfigError naming the bad value.
  void validate() const;
};

}  // namespace cslam
