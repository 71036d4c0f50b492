#pragma once
// 2D occupancy grid over a height band above the floor, from TSDF submaps (ROS nav_msgs
// conventions).
#include <cstdint>
#include <string>
#include <vector>

#include "geometry/se3.h"
#include "navmap/nav_config.h"
#include "navmap/submap_view.h"

namespace cslam {

// The grid frame: x and y span the floor plane, z is up, origin on the floor at the grid's
// lower-left corner (outer corner of cell (0, 0)). Cell (i, j) = column i, row j has its centre at
// T_world_grid * ((i + 0.5) r, (j + 0.5) r, 0). Row-major, row 0 at grid y = 0.
struct OccupancyGrid2D {
  static constexpr std::int8_t kFree = 0, kOccupied = 100, kUnknown = -1;
  int width = 0, height = 0;
  double resolution = 0.05;
  SE3 T_world_grid;
  std::vector<std::int8_t> cells;  // width * height values: 0 free, 100 occupied, -1 unknown

  bool empty() const { return cells.empty(); }
  std::int8_t at(int i, int j) const { return cells[std::size_t(j) * std::size_t(width) + std::size_t(i)]; }
  Eigen::Vector3d cell_center_world(int i, int j) const {
    return T_world_grid * Eigen::Vector3d((i + 0.5) * resolution, (j + 0.5) * resolution, 0.0);
  }
};

struct GridStats {
  std::size_t occupied = 0, free = 0, unknown = 0;    // cells
  std::size_t submaps_used = 0, submaps_skipped = 0;  // skipped: no volume or non-finite pose
  std::size_t band_voxels = 0, floor_samples = 0;     // evidence read
  std::size_t voxels_out_of_range = 0;                // beyond +-2^30 cells: ignored
};

struct GridResult {
  OccupancyGrid2D grid;  // empty when refused (error says why) or nothing was observed
  GridStats stats;
  std::string error;  // non-empty: the grid was refused (e.g. beyond config.max_cells)
};

// Orientation of the grid frame for a given up (unit): x is the world z axis (the first
// camera's viewing direction) projected on the floor plane, or world x when z is nearly
// vertical; y = up x x. Translation zero (build_occupancy_grid places the origin).
Eigen::Matrix3d grid_rotation(const Eigen::Vector3d& up);

// Rule, per submap and cell (voxels whose height above the floor is in [band_min, band_max]):
//   obstacle evidence (voxels with signed distance <= 0, and upward-facing zero crossings:
//   tops) >= min_occupied_voxels, and spanning >= min_obstacle_height or
//   >= min_obstacle_fill cell layers of voxels                             -> vote occupied
//   else the floor seen there (an upward crossing within floor_tolerance
//        of the floor), or free band voxels >= min_free_voxels reaching down
//        to band_min + min_obstacle_height                                 -> vote free
// Votes of all submaps add up as log-odds (log_odds_occupied / log_odds_free); a cell is
// occupied if the sum is > 0, free if < 0, unknown without votes. The grid covers the voted
// cells' bounding box; beyond config.max_cells it is refused (error). Throws ConfigError on a
// bad config, up or floor.
GridResult build_occupancy_grid(const SubmapViews& views, const Eigen::Vector3d& up, double floor_height,
                                const NavMapConfig& config);

}  // namespace cslam
