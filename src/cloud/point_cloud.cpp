#include "cloud/point_cloud.h"

#include <stdexcept>

namespace cslam {

void ColoredCloud::append(const ColoredCloud& other) {
  const bool was_empty = empty();
  const bool keep_colors = other.has_colors() && (was_empty || has_colors());
  const bool keep_normals = other.has_normals() && (was_empty || has_normals());
  points.insert(points.end(), other.points.begin(), other.points.end());
  if (keep_colors)
    colors.insert(colors.end(), other.colors.begin(), other.colors.end());
  else
    colors.clear();
  if (keep_normals)
    normals.insert(normals.end(), other.normals.begin(), other.normals.end());
  else
    normals.clear();
}

BoundingBox bounding_box(const std::vector<Eigen::Vector3f>& points) {
  if (points.empty()) throw std::invalid_argument("bounding_box: empty cloud");
  BoundingBox b;
  b.min = b.max = points.front();
  for (const auto& p : points) {
    b.min = b.min.cwiseMin(p);
    b.max = b.max.cwiseMax(p);
  }
  return b;
}

}  // namespace cslam
