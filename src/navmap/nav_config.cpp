#include "navmap/nav_config.h"

#include <cmath>
#include <string>

#include "core/error.h"

namespace cslam {

namespace {
void require(bool ok, const std::string& what) {
  if (!ok) throw ConfigError("navmap: " + what);
}
bool finite_vec(const Eigen::Vector3d& v) { return v.allFinite() && v.norm() > 1e-9; }
}  // namespace

void NavMapConfig::validate() const {
  require(!up || finite_vec(*up), "up must be a finite non-zero vector");
  require(finite_vec(default_up), "default_up must be a finite non-zero vector");
  require(!floor_height || std::isfinite(*floor_height), "floor_height must be finite");
  require(floor_bin > 0 && floor_bin <= 1.0, "floor_bin must be in (0, 1] m");
  require(floor_min_share > 0 && floor_min_share <= 1, "floor_min_share must be in (0, 1]");
  require(floor_percentile >= 0 && floor_percentile <= 1, "floor_percentile must be in [0, 1]");
  require(resolution >= 0.005 && resolution <= 10, "resolution must be in [0.005, 10] m");
  require(std::isfinite(band_min) && std::isfinite(band_max) && band_min < band_max, "band_min must be below band_max");
  require(std::isfinite(min_voxel_weight) && min_voxel_weight >= 0, "min_voxel_weight must be >= 0");
  require(min_occupied_voxels >= 1 && min_free_voxels >= 1, "min_occupied_voxels and min_free_voxels must be >= 1");
  require(std::isfinite(min_obstacle_height) && min_obstacle_height >= 0, "min_obstacle_height must be >= 0");
  require(std::isfinite(min_obstacle_fill) && min_obstacle_fill >= 0, "min_obstacle_fill must be >= 0");
  require(floor_tolerance >= 0 && floor_tolerance < band_max - band_min + 10, "floor_tolerance must be >= 0");
  require(std::isfinite(log_odds_occupied) && log_odds_occupied > 0, "log_odds_occupied must be > 0");
  require(std::isfinite(log_odds_free) && log_odds_free < 0, "log_odds_free must be < 0");
  require(max_cells >= 1, "max_cells must be >= 1");
  require(octomap_resolution >= 0.005 && octomap_resolution <= 10, "octomap_resolution must be in [0.005, 10] m");
  require(octomap_min_occupied_voxels >= 1, "octomap_min_occupied_voxels must be >= 1");
  require(max_octree_nodes >= 1, "max_octree_nodes must be >= 1");
}

}  // namespace cslam
