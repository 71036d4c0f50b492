#include "support/synth/surface_sampling.h"

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "core/error.h"

namespace cslam::synth {

SurfacePoints sample_surface_points(const Scene& scene, double spacing) {
  if (!(spacing > 0)) throw ConfigError("synth: surface sampling spacing must be positive");
  double area = 0;
  for (const Face& f : scene.faces) area += f.size_u * f.size_v;
  if (area / (spacing * spacing) > 5e7)
    throw ConfigError("synth: surface spacing " + std::to_string(spacing) + " m gives too many points");
  SurfacePoints out;
  for (const Face& f : scene.faces) {
    const bool floor = f.object < 0 && f.normal.z() > 0.5;
    const int nu = std::max(1, static_cast<int>(std::round(f.size_u / spacing)));
    const int nv = std::max(1, static_cast<int>(std::round(f.size_v / spacing)));
    const double du = f.size_u / nu, dv = f.size_v / nv;
    for (int j = 0; j < nv; ++j)
      for (int i = 0; i < nu; ++i) {
        const double s = (i + 0.5) * du, t = (j + 0.5) * dv;
        if (!f.contains(s, t)) continue;
        const Eigen::Vector3d p = f.point(s, t);
        if (floor) {
          bool covered = false;
          for (const auto& fu : scene.furniture) covered = covered || fu.footprint_distance(p.head<2>()) <= 0;
          if (covered) continue;
        }
        const cv::Vec3b bgr = scene.color_at(f, s, t);
        out.points.push_back(p.cast<float>());
        out.colors.push_back({bgr[2], bgr[1], bgr[0]});
        out.normals.push_back(f.normal.cast<float>());
      }
  }
  return out;
}

namespace {
const char* kHeaderBody =
    "property float x\nproperty float y\nproperty float z\n"
    "property uchar red\nproperty uchar green\nproperty uchar blue\n"
    "property float nx\nproperty float ny\nproperty float nz\nend_header\n";
constexpr size_t kRecord = 3 * 4 + 3 + 3 * 4;
}  // namespace

void write_ply(const std::string& path, const SurfacePoints& cloud) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw InputError(path, "cannot create file");
  out << "ply\nformat binary_little_endian 1.0\ncomment cslam-synth ground-truth surface\nelement vertex "
      << cloud.size() << "\n"
      << kHeaderBody;
  std::vector<char> buf(kRecord * cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {  // x86/ARM hosts are little-endian: plain copies
    char* r = buf.data() + i * kRecord;
    std::memcpy(r, cloud.points[i].data(), 12);
    std::memcpy(r + 12, cloud.colors[i].data(), 3);
    std::memcpy(r + 15, cloud.normals[i].data(), 12);
  }
  out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
  if (!out) throw InputError(path, "write failed");
}

SurfacePoints read_ply(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open file");
  std::string line, header;
  size_t count = 0;
  bool have_count = false;
  for (int n = 0; std::getline(in, line); ++n) {
    if (n == 0 && line != "ply") throw InputError(path, "not a PLY file");
    if (n == 1 && line != "format binary_little_endian 1.0")
      throw InputError(path, "only binary little-endian PLY is supported");
    if (line.rfind("element vertex ", 0) == 0) {
      count = std::stoull(line.substr(15));
      have_count = true;
      continue;
    }
    if (line.rfind("property", 0) == 0 || line == "end_header") header += line + "\n";
    if (line == "end_header") break;
  }
  if (!have_count || header != kHeaderBody)
    throw InputError(path, "unexpected PLY header (expected x y z red green blue nx ny nz)");
  std::vector<char> buf(kRecord * count);
  in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
  if (static_cast<size_t>(in.gcount()) != buf.size()) throw InputError(path, "truncated vertex data");
  SurfacePoints cloud;
  cloud.points.resize(count);
  cloud.colors.resize(count);
  cloud.normals.resize(count);
  for (size_t i = 0; i < count; ++i) {
    const char* r = buf.data() + i * kRecord;
    std::memcpy(cloud.points[i].data(), r, 12);
    std::memcpy(cloud.colors[i].data(), r + 12, 3);
    std::memcpy(cloud.normals[i].data(), r + 15, 12);
  }
  return cloud;
}

}  // namespace cslam::synth
