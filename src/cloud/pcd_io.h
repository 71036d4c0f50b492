#pragma once
// Our own PCD v0.7 writer (fields x y z rgb, as PCL's PointXYZRGB), binary or ASCII.
#include <string>

#include "cloud/point_cloud.h"

namespace cslam {

// Throws std::invalid_argument on an empty cloud, InputError if the file cannot be written.
// A cloud without colours is written with rgb = 0. Writes atomically (temp file + rename).
void write_pcd(const std::string& path, const ColoredCloud& cloud, bool binary = true);

}  // namespace cslam
