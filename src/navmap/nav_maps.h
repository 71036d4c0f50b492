#pragma once
// One call from the dense map (TSDF submaps + the group's keyframe poses) to the navigation
// maps: up and floor, the 2D occupancy grid and the OctoMap .bt.
#include <string>
#include <vector>

#include "navmap/nav_config.h"
#include "navmap/occupancy_grid.h"
#include "navmap/octomap_export.h"
#include "navmap/up_floor.h"

namespace cslam {

struct NavMapStats {
  std::size_t cells_occupied = 0, cells_free = 0, cells_unknown = 0;
  std::size_t octree_nodes = 0, octree_occupied_leaves = 0, octree_free_leaves = 0;
  std::size_t submaps_used = 0, submaps_skipped = 0;  // skipped: null volume or non-finite pose
  std::size_t cameras_used = 0, cameras_skipped = 0;  // skipped: non-finite pose
  std::size_t floor_samples = 0;
  double up_floor_ms = 0, grid_ms = 0, octomap_ms = 0, total_ms = 0;
};

struct NavMaps {
  OccupancyGrid2D grid;    // empty if nothing observed or refused (grid_error)
  std::string octomap_bt;  // empty if off, nothing observed or refused (octomap_error)
  Eigen::Vector3d up{0, 0, 1};
  double floor = 0;  // height of the floor along up (world frame)
  bool up_estimated = false, floor_estimated = false;
  std::string floor_rule;  // "given", "peak", "percentile" or "none" (no surface: no maps)
  std::string grid_error, octomap_error;
  NavMapStats stats;
};

// Up: config.up if given, else estimate_up(T_world_cams, config.default_up). Floor:
// config.floor_height if given, else estimate_floor. Then build_occupancy_grid and (if
// config.octomap) build_octomap. Never throws on bad data (unusable views and poses are counted,
// budgets refuse with an error string); throws ConfigError on a bad config.
NavMaps build_nav_maps(const SubmapViews& views, const std::vector<SE3>& T_world_cams, const NavMapConfig& config);

}  // namespace cslam
