#pragma once
// ROS map_server files of an occupancy grid: a binary PGM image and its YAML description.
#include <string>

#include "navmap/occupancy_grid.h"

namespace cslam {

// Binary PGM (P5, maxval 255): occupied 0, free 254, unknown 205 (map_server's trinary reading
// with negate 0). Image row 0 is the TOP of the map, i.e. the grid's last row (j = height - 1).
// An empty grid gives a 0 x 0 image.
std::string to_pgm(const OccupancyGrid2D& grid);

// map_server YAML for the PGM saved as image_file: resolution, origin [0, 0, 0] (the lower-left
// pixel's corner in the grid's own frame, which is where the grid frame's origin is: the grid
// frame sits in the SLAM world at grid.T_world_grid, given as a comment), negate 0,
// occupied_thresh 0.65, free_thresh 0.196, mode trinary.
std::string to_map_yaml(const OccupancyGrid2D& grid, const std::string& image_file);

}  // namespace cslam
