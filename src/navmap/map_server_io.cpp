#include "navmap/map_server_io.h"

#include <cstdio>
#include <sstream>

namespace cslam {

std::string to_pgm(const OccupancyGrid2D& g) {
  const int w = g.empty() ? 0 : g.width, h = g.empty() ? 0 : g.height;
  std::string out = "P5\n" + std::to_string(w) + " " + std::to_string(h) + "\n255\n";
  const std::size_t header = out.size();
  out.resize(header + std::size_t(w) * std::size_t(h));
  for (int row = 0; row < h; ++row) {
    const int j = h - 1 - row;  // image top = the grid's last row
    char* dst = &out[header + std::size_t(row) * std::size_t(w)];
    for (int i = 0; i < w; ++i) {
      const std::int8_t v = g.at(i, j);
      dst[i] = char(v == OccupancyGrid2D::kOccupied ? 0 : v == OccupancyGrid2D::kFree ? 254 : 205);
    }
  }
  return out;
}

namespace {
std::string num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}
// YAML double-quoted scalar (escapes quotes, backslashes and control characters).
std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (unsigned char ch : s) {
    if (ch == '"' || ch == '\\')
      out += '\\', out += char(ch);
    else if (ch < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", ch);
      out += buf;
    } else
      out += char(ch);
  }
  return out + "\"";
}
}  // namespace

std::string to_map_yaml(const OccupancyGrid2D& g, const std::string& image_file) {
  const Eigen::Vector3d& t = g.T_world_grid.translation();
  const Eigen::Quaterniond& q = g.T_world_grid.rotation();
  std::ostringstream y;
  y << "# cslam occupancy grid (ROS map_server). The map's frame is the grid frame: x/y on the floor,\n"
       "# z up, origin at the lower-left corner of the image on the floor. It sits in the SLAM world\n"
       "# (the first camera's frame) at T_world_grid = [tx ty tz qx qy qz qw]:\n"
    << "# T_world_grid: [" << num(t.x()) << ", " << num(t.y()) << ", " << num(t.z()) << ", " << num(q.x()) << ", "
    << num(q.y()) << ", " << num(q.z()) << ", " << num(q.w()) << "]\n"
    << "image: " << quoted(image_file) << "\n"
    << "mode: trinary\n"
    << "resolution: " << num(g.resolution) << "\n"
    << "origin: [0.0, 0.0, 0.0]\n"
    << "negate: 0\n"
    << "occupied_thresh: 0.65\n"
    << "free_thresh: 0.196\n";
  return y.str();
}

}  // namespace cslam
