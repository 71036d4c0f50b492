#pragma once
// 3D occupancy of TSDF submaps as an OctoMap octree in its binary .bt format (world frame).
#include <string>

#include "navmap/nav_config.h"
#include "navmap/submap_view.h"

namespace cslam {

struct OctomapResult {
  std::string bt;  // the .bt file's bytes (octomap::OcTree::writeBinary); empty if refused or no voxel
  std::size_t nodes = 0, occupied_leaves = 0, free_leaves = 0;  // after pruning
  std::size_t submaps_used = 0, submaps_skipped = 0, voxels_out_of_range = 0;
  std::string error;  // non-empty: refused (node budget)
};

// Leaves of config.octomap_resolution in the world frame. Per submap and leaf: >=
// octomap_min_occupied_voxels obstacle voxels (signed distance <= 0) -> one occupied update,
// else any free voxel -> one free update (OctoMap's hit/miss log-odds, so submaps vote as in the
// 2D grid). Then updateInnerOccupancy() and the .bt as OcTree::writeBinary writes it (maximum
// likelihood, pruned). Stops and refuses when the tree grows
// beyond config.max_octree_nodes. Throws ConfigError on a bad config.
OctomapResult build_octomap(const SubmapViews& views, const NavMapConfig& config);

// build_octomap(...).bt
std::string to_octomap_bt(const SubmapViews& views, const NavMapConfig& config);

}  // namespace cslam
