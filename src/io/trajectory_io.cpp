#include "io/trajectory_io.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "core/error.h"
#include "io/text_table.h"

namespace cslam {

Trajectory read_tum_trajectory(const std::string& path) {
  Trajectory out;
  for_each_text_row(path, [&](int line, const std::vector<std::string>& tok) {
    if (tok.size() != 8)
      throw InputError(path, line,
                       "expected 8 values 'timestamp x y z qx qy qz qw', got " + std::to_string(tok.size()));
    double v[8];
    static const char* names[8] = {"timestamp", "x", "y", "z", "qx", "qy", "qz", "qw"};
    for (int i = 0; i < 8; ++i) v[i] = parse_double(tok[i], path, line, names[i]);
    Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    if (q.norm() < 1e-6) throw InputError(path, line, "quaternion has zero length");
    out.push_back({v[0], SE3(q.normalized(), Eigen::Vector3d(v[1], v[2], v[3]))});
  });
  return out;
}

bool tum_stamp_ok(double timestamp) { return std::isfinite(timestamp) && std::abs(timestamp) <= kMaxTumTimestamp; }

std::string format_tum_line(const StampedPose& p) {
  const auto& t = p.T_world_cam.translation();
  const auto& q = p.T_world_cam.rotation();
  const double stamp = tum_stamp_ok(p.timestamp) ? p.timestamp : std::nan("");
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%.6f %.6f %.6f %.6f %.7f %.7f %.7f %.7f", stamp, t.x(), t.y(), t.z(), q.x(), q.y(),
                q.z(), q.w());
  return buf;
}

void write_tum_trajectory(const std::string& path, const Trajectory& trajectory, const std::string& header) {
  std::size_t bad_stamps = 0;
  for (const auto& p : trajectory) {
    if (!p.T_world_cam.is_finite())
      throw std::invalid_argument("write_tum_trajectory(" + path +
                                  "): non-finite pose at t=" + std::to_string(p.timestamp));
    bad_stamps += !tum_stamp_ok(p.timestamp);
  }
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp);
    if (!out) throw InputError(path, "cannot write trajectory file");
    if (!header.empty()) out << "# " << header << "\n";
    out << "# timestamp x y z qx qy qz qw (T_world_cam)\n";
    if (bad_stamps > 0) out << "# " << bad_stamps << " poses with a non-finite or out-of-range timestamp left out\n";
    for (const auto& p : trajectory)
      if (tum_stamp_ok(p.timestamp)) out << format_tum_line(p) << "\n";
    if (!out) throw InputError(path, "write failed");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw InputError(path, "cannot rename temporary file: " + ec.message());
}

void sort_by_time(Trajectory& trajectory) {
  std::stable_sort(trajectory.begin(), trajectory.end(),
                   [](const StampedPose& a, const StampedPose& b) { return a.timestamp < b.timestamp; });
}

std::optional<SE3> interpolate_pose(const Trajectory& trajectory, double t, double max_gap_s) {
  if (trajectory.size() < 2) return std::nullopt;
  auto it = std::lower_bound(trajectory.begin(), trajectory.end(), t,
                             [](const StampedPose& p, double x) { return p.timestamp < x; });
  if (it == trajectory.end() || (it == trajectory.begin() && it->timestamp > t)) return std::nullopt;
  if (it->timestamp == t) return it->T_world_cam;
  const StampedPose& b = *it;
  const StampedPose& a = *(it - 1);
  const double gap = b.timestamp - a.timestamp;
  if (gap <= 0 || gap > max_gap_s) return std::nullopt;
  const double s = (t - a.timestamp) / gap;
  const Eigen::Quaterniond q = a.T_world_cam.rotation().slerp(s, b.T_world_cam.rotation());
  const Eigen::Vector3d p = (1 - s) * a.T_world_cam.translation() + s * b.T_world_cam.translation();
  return SE3(q, p);
}

}  // namespace cslam
