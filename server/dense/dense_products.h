#pragma once
// What readers make of the live dense map's view: the submaps of each group, a group's fused
// mesh and cloud (the union of its submaps placed in the world), and the compact binary mesh
// of one submap for the viewer (CSM1, docs/http.md). Pure functions of an immutable view.
#include <map>
#include <string>
#include <vector>

#include "cloud/point_cloud.h"
#include "dense/live_dense_map.h"
#include "navmap/nav_maps.h"

namespace cslam::server {

// Group id -> its submaps (pointers into `view`), groups in id order, submaps by id.
std::map<int, std::vector<const DenseSubmapView*>> submaps_by_group(const DenseMapView& view);
// The group with most submaps (-1: none).
int largest_group(const DenseMapView& view);

TriangleMesh group_mesh(const std::vector<const DenseSubmapView*>& submaps);
// One point per occupied voxel of the submaps' voxel size (overlaps merged).
ColoredCloud group_cloud(const std::vector<const DenseSubmapView*>& submaps);

// CSM1: "CSM1", uint32 version, uint32 vertex count, uint32 triangle count, float32 xyz per
// vertex, uint8 rgb per vertex padded to 4 bytes, uint32 indices; little-endian.
std::string encode_csm1(const TriangleMesh& mesh, std::uint32_t version);

// Navigation maps of a group from its submaps' coarse volumes; the cameras are the submaps'
// reference keyframes (for the up direction).
NavMaps group_nav_maps(const std::vector<const DenseSubmapView*>& submaps, const NavMapConfig& config = {});

// Writes dense_mesh_G.ply, dense_cloud_G.ply, occupancy_G.pgm + .yaml and octomap_G.bt and dense_cloud_G.ply for every
// group with a mesh into dir; returns the files written.
std::vector<std::string> write_dense_outputs(const DenseMapView& view, const std::string& dir);

}  // namespace cslam::server
