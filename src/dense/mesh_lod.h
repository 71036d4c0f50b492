#pragma once
// Mesh helpers for the live dense map's readers: a coarser level of detail by vertex clustering
// (far submaps in a viewer), and the union of submap meshes placed in the world (a group's mesh
// and cloud).
#include <vector>

#include "cloud/point_cloud.h"
#include "geometry/se3.h"

namespace cslam {

// Vertices merged per cube of side `cell` (position and colour averaged), triangles remapped;
// triangles that collapse, and repeats of one triangle, are dropped.
TriangleMesh simplify_by_clustering(const TriangleMesh& mesh, float cell);

struct PlacedMesh {
  const TriangleMesh* mesh = nullptr;
  SE3 T_world_mesh;
};

// One mesh in the world frame: every mesh's vertices moved by its pose, indices offset.
TriangleMesh merge_meshes(const std::vector<PlacedMesh>& meshes);

// The vertices of the placed meshes as a cloud with one point per occupied cube of side `voxel`
// (mean position and colour): overlapping submaps do not double the surface.
ColoredCloud mesh_vertices_cloud(const std::vector<PlacedMesh>& meshes, float voxel);

}  // namespace cslam
