#pragma once
// Ground-truth surface of the synthetic scene as a point cloud (for reconstruction accuracy):
// every face sampled on a regular grid (uniform density), with the shaded colour and the face
// normal; floor under furniture is left out. Stored as binary little-endian PLY:
//   float x y z, uchar red green blue, float nx ny nz.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "support/synth/scene.h"

namespace cslam::synth {

struct SurfacePoints {
  std::vector<Eigen::Vector3f> points;
  std::vector<std::array<std::uint8_t, 3>> colors;  // r, g, b
  std::vector<Eigen::Vector3f> normals;
  size_t size() const { return points.size(); }
};

// Throws ConfigError if spacing is not positive or would give more than ~50 million points.
SurfacePoints sample_surface_points(const Scene& scene, double spacing);

// Throws InputError naming the path if the file cannot be written.
void write_ply(const std::string& path, const SurfacePoints& cloud);
// Reads a PLY written by write_ply (binary little-endian, exactly these properties). Throws
// InputError naming the path on anything else.
SurfacePoints read_ply(const std::string& path);

}  // namespace cslam::synth
