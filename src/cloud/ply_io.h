#pragma once
// Our own PLY reader/writer (PCL's io component is not used: it drags VTK and MPI in).
// Writing: binary little-endian, vertex x y z (float), optional nx ny nz (float), red green blue
// (uchar); meshes add "element face" with "property list uchar int vertex_indices".
// Reading: ascii or binary_little_endian, any scalar property types; x y z are required,
// red/green/blue (or r/g/b, diffuse_*) and nx/ny/nz are taken when present; faces (triangles
// only, polygons are fanned) are read by read_ply_mesh. Other elements are skipped.
#include <string>

#include "cloud/point_cloud.h"

namespace cslam {

// Throws std::invalid_argument on an empty cloud (an empty file would look valid) or on
// mismatched colour/normal counts; InputError if the file cannot be written. Writes atomically.
void write_ply(const std::string& path, const ColoredCloud& cloud);
void write_ply_mesh(const std::string& path, const TriangleMesh& mesh);

// The same bytes in memory (HTTP downloads); throw std::invalid_argument on an empty input.
std::string ply_bytes(const ColoredCloud& cloud);
std::string ply_mesh_bytes(const TriangleMesh& mesh);

// Throws InputError naming the file on any malformed or unsupported content.
ColoredCloud read_ply(const std::string& path);
TriangleMesh read_ply_mesh(const std::string& path);

}  // namespace cslam
