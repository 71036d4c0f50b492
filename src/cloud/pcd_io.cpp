#include "cloud/pcd_io.h"

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "core/error.h"

namespace cslam {

void write_pcd(const std::string& path, const ColoredCloud& cloud, bool binary) {
  if (cloud.empty()) throw std::invalid_argument("refusing to write an empty point cloud to " + path);
  if (cloud.has_colors() && cloud.colors.size() != cloud.size())
    throw std::invalid_argument("write_pcd: colour count differs from point count");
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw InputError(path, "cannot open for writing");
    out << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\n"
        << "COUNT 1 1 1 1\nWIDTH " << cloud.size() << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << cloud.size()
        << "\nDATA " << (binary ? "binary" : "ascii") << "\n";
    std::string buf;
    buf.reserve(binary ? 16 * cloud.size() : 48 * cloud.size());
    char line[96];
    for (size_t i = 0; i < cloud.size(); ++i) {
      const auto& p = cloud.points[i];
      std::uint32_t rgb = 0;
      if (cloud.has_colors())
        rgb = (std::uint32_t(cloud.colors[i][0]) << 16) | (std::uint32_t(cloud.colors[i][1]) << 8) | cloud.colors[i][2];
      if (binary) {
        char b[16];
        std::memcpy(b, p.data(), 12);
        std::memcpy(b + 12, &rgb, 4);
        buf.append(b, 16);
      } else {
        const int n = std::snprintf(line, sizeof(line), "%.7g %.7g %.7g %u\n", p.x(), p.y(), p.z(), rgb);
        buf.append(line, size_t(n));
      }
    }
    out.write(buf.data(), std::streamsize(buf.size()));
    if (!out) throw InputError(path, "write failed");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw InputError(path, "cannot rename temporary file: " + ec.message());
}

}  // namespace cslam
