#pragma once
// Configuration of the navigation maps made from the dense map (2D occupancy grid, OctoMap).
#include <cstddef>
#include <optional>

#include <Eigen/Core>

namespace cslam {

struct NavMapConfig {
  // --- Up direction and floor -------------------------------------------------------------
  // Given: used as is (normalised). Otherwise estimated from the cameras (estimate_up).
  std::optional<Eigen::Vector3d> up;
  // Up when it cannot be estimated (no usable camera): the SLAM world is the first camera's
  // frame, whose -y axis is up for a level camera.
  Eigen::Vector3d default_up{0.0, -1.0, 0.0};
  // Given: the floor's height along up (metres, world frame). Otherwise estimate_floor.
  std::optional<double> floor_height;
  double floor_bin = 0.01;         // histogram bin of upward-facing surface heights (m)
  double floor_min_share = 0.05;   // a floor bin holds >= this share of all upward-facing samples
  double floor_percentile = 0.02;  // fallback rule when no bin qualifies: this low percentile

  // --- 2D occupancy grid ----------------------------------------------------------------------
  double resolution = 0.05;                 // cell side (m)
  double band_min = 0.10, band_max = 1.60;  // obstacle band, metres above the floor
  float min_voxel_weight = 0.0f;            // voxels with weight <= this are ignored
  int min_occupied_voxels = 3;              // a submap calls a cell occupied with >= this many obstacle voxels
  // ... and either spanning at least min_obstacle_height (a side seen), or at least
  // min_obstacle_fill * (resolution / voxel)^2 of them (a top seen from above covering the cell).
  // A noisy depth pixel makes a short streak of truncation length along its ray: neither.
  double min_obstacle_height = 0.10;
  double min_obstacle_fill = 1.0;
  int min_free_voxels = 3;        // ... free with >= this many free band voxels (and no obstacle)
  double floor_tolerance = 0.05;  // a floor crossing within this of the floor: floor seen (free)
  // Per-submap votes combined as log-odds (OctoMap's hit/miss defaults, p = 0.7 / 0.4): one
  // submap seeing an obstacle outweighs one seeing free space, two free ones outweigh it.
  float log_odds_occupied = 0.85f, log_odds_free = -0.405f;
  std::size_t max_cells = std::size_t(4096) * 4096;  // grids larger than this are refused

  // --- 3D OctoMap -----------------------------------------------------------------------------
  bool octomap = true;                       // false: no .bt (only the grid)
  double octomap_resolution = 0.05;          // leaf size (m)
  int octomap_min_occupied_voxels = 2;       // per submap and leaf, as min_occupied_voxels
  std::size_t max_octree_nodes = 4'000'000;  // the .bt is refused beyond this many nodes

  // Throws ConfigError naming the first impossible value.
  void validate() const;
};

}  // namespace cslam
