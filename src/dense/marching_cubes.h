#pragma once
// Marching-cubes case tables, generated at start-up from the cube's geometry instead of being
// pasted from elsewhere: for each face, every run of "inside" corners (value < iso) is cut off
// by one iso-line segment (so on an ambiguous face the inside corners stay apart, the same
// choice on both cubes sharing the face: no cracks); the segments chain into closed loops over
// the cube's surface, which are fanned into triangles.
//
// Corner i sits at offset (i & 1, (i >> 1) & 1, (i >> 2) & 1). Edge e = 4 * axis + j joins
// mc_edge_corner(e, 0) and mc_edge_corner(e, 1) = mc_edge_corner(e, 0) + unit(axis).
#include <array>
#include <vector>

namespace cslam {

using McTriangle = std::array<int, 3>;  // cube edge ids

// Triangles of configuration `config` (bit i set = corner i inside); counter-clockwise seen
// from outside (normals point from inside to outside, i.e. towards increasing values).
const std::vector<McTriangle>& mc_triangles(int config);
int mc_edge_corner(int edge, int end);
int mc_edge_axis(int edge);

}  // namespace cslam
