#pragma once
// Plain coloured point clouds and triangle meshes (no PCL types in the interface).
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace cslam {

using Rgb8 = std::array<std::uint8_t, 3>;  // red, green, blue

// Points in one frame; colours and normals are either empty or one per point.
struct ColoredCloud {
  std::vector<Eigen::Vector3f> points;
  std::vector<Rgb8> colors;
  std::vector<Eigen::Vector3f> normals;

  std::size_t size() const { return points.size(); }
  bool empty() const { return points.empty(); }
  bool has_colors() const { return !colors.empty(); }
  bool has_normals() const { return !normals.empty(); }
  void reserve(std::size_t n) {
    points.reserve(n);
    colors.reserve(n);
  }
  // Appends other (colours/normals kept only if both clouds have them, or this one is empty).
  void append(const ColoredCloud& other);
};

// Indexed triangle mesh with per-vertex colours (empty or one per vertex).
struct TriangleMesh {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<Rgb8> colors;
  std::vector<std::array<std::uint32_t, 3>> triangles;
};

struct BoundingBox {
  Eigen::Vector3f min{0, 0, 0}, max{0, 0, 0};
  Eigen::Vector3f center() const { return 0.5f * (min + max); }
  float diagonal() const { return (max - min).norm(); }
};
// Axis-aligned bounds; throws std::invalid_argument on an empty cloud.
BoundingBox bounding_box(const std::vector<Eigen::Vector3f>& points);

}  // namespace cslam
