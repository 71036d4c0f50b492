#include "support/synth/trajectory_planner.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <sstream>

#include "core/error.h"
#include "support/synth/random.h"

namespace cslam::synth {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

struct PathPoint {
  Eigen::Vector3d position;
  double yaw = 0, pitch = 0;
};
using PathFn = std::function<PathPoint(double phi)>;

std::string fmt(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

int ramp_frames(const TrajectoryConfig& c, int frames) {
  const int lo = std::min(static_cast<int>(c.rate_hz), frames / 4);
  return std::max(1, std::max(lo, static_cast<int>(c.ramp_fraction * frames)));
}

// Normalised progress g(i) in [0, 1] for frames i = 0..n-1: at rest at both ends, cosine ramps
// of `ramp` frames, constant speed in between.
std::vector<double> progress_profile(int n, int ramp) {
  std::vector<double> vel(n, 1.0), g(n, 0.0);
  for (int i = 0; i < n; ++i) {
    const int d = std::min(i, n - 1 - i);
    if (d < ramp) vel[i] = 0.5 * (1 - std::cos(kPi * d / ramp));
  }
  for (int i = 1; i < n; ++i) g[i] = g[i - 1] + 0.5 * (vel[i - 1] + vel[i]);
  for (auto& x : g) x /= std::max(g.back(), 1e-12);
  return g;
}

// Samples the path at n frames with constant-speed (in arc length) motion shaped by the profile.
Trajectory sample_path(const PathFn& path, double phi0, double phi1, int n, int ramp, double t0, double rate) {
  const int m = 4000;
  std::vector<double> phis(m + 1), len(m + 1, 0.0);
  Eigen::Vector3d prev = path(phi0).position;
  for (int j = 0; j <= m; ++j) {
    phis[j] = phi0 + (phi1 - phi0) * j / m;
    const Eigen::Vector3d p = path(phis[j]).position;
    if (j > 0) len[j] = len[j - 1] + (p - prev).norm() + 1e-9;  // tiny term keeps it strictly increasing
    prev = p;
  }
  const auto g = progress_profile(n, ramp);
  Trajectory out;
  for (int i = 0; i < n; ++i) {
    const double target = g[i] * len[m];
    const int j = std::clamp(static_cast<int>(std::lower_bound(len.begin(), len.end(), target) - len.begin()), 1, m);
    const double a = (target - len[j - 1]) / (len[j] - len[j - 1]);
    const PathPoint p = path(phis[j - 1] + a * (phis[j] - phis[j - 1]));
    out.push_back({t0 + i / rate, camera_pose(p.position, p.yaw, p.pitch)});
  }
  return out;
}

void step_stats(const Trajectory& t, double& max_step, double& max_rot) {
  max_step = max_rot = 0;
  for (size_t i = 1; i < t.size(); ++i) {
    max_step = std::max(max_step, (t[i].T_world_cam.translation() - t[i - 1].T_world_cam.translation()).norm());
    max_rot = std::max(max_rot, (t[i - 1].T_world_cam.inverse() * t[i].T_world_cam).rotation_angle());
  }
}

// Arc length of the walkway ellipse from phi0 to phi1.
double ellipse_length(const Walkway& w, double phi0, double phi1) {
  double len = 0;
  const int n = 2000;
  for (int i = 0; i < n; ++i)
    len += (w.at(phi0 + (phi1 - phi0) * (i + 1) / n) - w.at(phi0 + (phi1 - phi0) * i / n)).norm();
  return len;
}

double span_for_length(const Walkway& w, double phi0, double length) {
  double span = 0;
  const double dphi = 0.001;
  while (ellipse_length(w, phi0, phi0 + span + dphi) < length && span < 8 * kPi) span += dphi * 16;
  return span;
}

}  // namespace

void TrajectoryConfig::validate() const {
  if (robots < 1) throw ConfigError("synth: need at least one robot, got " + std::to_string(robots));
  if (frames < 10) throw ConfigError("synth: need at least 10 frames per robot, got " + std::to_string(frames));
  if (!(rate_hz > 0)) throw ConfigError("synth: frame rate must be positive");
  if (!(overlap >= 0 && overlap < 1)) throw ConfigError("synth: overlap must be in [0, 1), got " + fmt(overlap));
  if (!(speed > 0) || !(max_step > 0) || !(max_rotation_deg > 0))
    throw ConfigError("synth: speed and per-frame limits must be positive");
  if (!(min_height > 0 && max_height > min_height + 0.2))
    throw ConfigError("synth: need 0 < min_height < max_height - 0.2");
  if (!(ramp_fraction > 0 && ramp_fraction <= 0.25)) throw ConfigError("synth: ramp_fraction must be in (0, 0.25]");
}

SE3 interpolate_pose(const SE3& a, const SE3& b, double alpha) {
  return SE3(a.rotation().slerp(alpha, b.rotation()), (1 - alpha) * a.translation() + alpha * b.translation());
}

SE3 camera_pose(const Eigen::Vector3d& position, double yaw, double pitch) {
  const Eigen::Vector3d forward(std::cos(pitch) * std::cos(yaw), std::cos(pitch) * std::sin(yaw), std::sin(pitch));
  const Eigen::Vector3d right(std::sin(yaw), -std::cos(yaw), 0.0);
  const Eigen::Vector3d down = forward.cross(right);
  Eigen::Matrix3d R;
  R.col(0) = right;
  R.col(1) = down;
  R.col(2) = forward;
  return SE3(R, position);
}

TrajectoryPlan plan_trajectories(const Scene& scene, const TrajectoryConfig& config) {
  config.validate();
  if (config.max_height > scene.config.height - 0.3)
    throw ConfigError("synth: robots up to " + fmt(config.max_height) + " m do not fit under a " +
                      fmt(scene.config.height) + " m ceiling");
  Rng rng(derive_seed(scene.config.seed, 2));
  const Walkway& w = scene.walkway;
  const int n = config.frames, ramp = ramp_frames(config, n);
  const double usable = (n - 1) - ramp;  // frames at full speed equivalent
  const double max_rot = config.max_rotation_deg * kDeg;
  // Smooth view variations that depend on the place only, so robots at the same place look alike.
  const double yaw_amp = 12 * kDeg, pitch_amp = 5 * kDeg, height_amp = 0.08;
  const double psi1 = rng.uniform(0, 2 * kPi), psi2 = rng.uniform(0, 2 * kPi), psi3 = rng.uniform(0, 2 * kPi);
  double phi_next = rng.uniform(0, 2 * kPi);

  TrajectoryPlan plan;
  for (int k = 0; k < config.robots; ++k) {
    RobotPlan rp;
    if (k == 0 && config.loop) {
      const double needed = 2 * kPi / (0.95 * max_rot) + ramp + 1;
      if (n < needed)
        throw ConfigError("synth: a loop (full turn at <= " + fmt(config.max_rotation_deg) +
                          " deg/frame) needs at least " + std::to_string(static_cast<int>(std::ceil(needed))) +
                          " frames, got " + std::to_string(n) + " (use more --frames or no loop)");
      rp.kind = "loop";
      rp.radius = std::min({0.8 * w.b, 0.8 * w.a, 1.0, 0.95 * config.max_step * usable / (2 * kPi)});
      rp.base_height = std::clamp(1.0, config.min_height + 0.1, config.max_height - 0.1);
      rp.phi_start = rng.uniform(0, 2 * kPi);
      rp.phi_end = rp.phi_start + 2 * kPi;
      const double r = rp.radius, h = rp.base_height, c_pitch = -2 * kDeg;
      const PathFn path = [&w, r, h, c_pitch](double phi) {
        return PathPoint{Eigen::Vector3d(w.center.x() + r * std::cos(phi), w.center.y() + r * std::sin(phi), h), phi,
                         c_pitch};
      };
      rp.trajectory = sample_path(path, rp.phi_start, rp.phi_end, n, ramp, config.start_time, config.rate_hz);
    } else {
      rp.kind = "arc";
      rp.base_height = std::clamp(rng.uniform(0.75, 1.25), config.min_height + height_amp + 0.02,
                                  config.max_height - height_amp - 0.02);
      const double h = rp.base_height;
      const double pitch0 = (0.9 - h) * 8 * kDeg;  // low robots look up a little, high ones down
      const PathFn path = [&w, h, pitch0, yaw_amp, pitch_amp, height_amp, psi1, psi2, psi3](double phi) {
        const Eigen::Vector2d p = w.at(phi);
        return PathPoint{Eigen::Vector3d(p.x(), p.y(), h + height_amp * std::sin(phi + psi3)),
                         phi + yaw_amp * std::sin(3 * phi + psi1), pitch0 + pitch_amp * std::sin(2 * phi + psi2)};
      };
      rp.phi_start = phi_next;
      double span = span_for_length(w, rp.phi_start, config.speed / config.rate_hz * usable);
      for (int iter = 0; iter < 20; ++iter) {
        rp.phi_end = rp.phi_start + span;
        rp.trajectory = sample_path(path, rp.phi_start, rp.phi_end, n, ramp, config.start_time, config.rate_hz);
        double ms = 0, mr = 0;
        step_stats(rp.trajectory, ms, mr);
        const double factor = std::min(0.95 * config.max_step / ms, 0.95 * max_rot / mr);
        if (factor >= 1.0) break;
        span *= factor * 0.99;
      }
      phi_next = rp.phi_start + (1.0 - config.overlap) * (rp.phi_end - rp.phi_start);
    }
    const TrajectoryCheck check = check_trajectory(scene, rp.trajectory, config);
    if (!check.ok)
      throw ConfigError("synth: robot " + std::to_string(k + 1) + " trajectory does not fit: " + check.problem);
    plan.robots.push_back(std::move(rp));
  }
  return plan;
}

Trajectory make_whole_sequence(const TrajectoryPlan& plan, const TrajectoryConfig& config) {
  Trajectory out;
  auto append = [&](const SE3& T) { out.push_back({config.start_time + out.size() / config.rate_hz, T}); };
  for (size_t k = 0; k < plan.robots.size(); ++k) {
    const Trajectory& t = plan.robots[k].trajectory;
    if (t.empty()) continue;
    if (!out.empty()) {
      // Straight transition at rest at both ends (cosine profile peaks at pi/2 times the mean speed).
      const SE3 a = out.back().T_world_cam, b = t.front().T_world_cam;
      const double dist = (b.translation() - a.translation()).norm(), ang = (a.inverse() * b).rotation_angle();
      const double mean_limit = 0.9 / (kPi / 2);
      // Also keep the peak acceleration d/2 (pi/T)^2 below 0.8 m/s^2.
      const double accel_frames = config.rate_hz * kPi * std::sqrt(dist / (2 * 0.8));
      const int steps = std::max(
          2,
          static_cast<int>(std::ceil(std::max({dist / (config.max_step * mean_limit),
                                               ang / (config.max_rotation_deg * kDeg * mean_limit), accel_frames}))));
      for (int i = 1; i < steps; ++i) append(interpolate_pose(a, b, 0.5 * (1 - std::cos(kPi * i / steps))));
    }
    for (const auto& p : t) append(p.T_world_cam);
  }
  return out;
}

TrajectoryCheck check_trajectory(const Scene& scene, const Trajectory& trajectory, const TrajectoryConfig& limits,
                                 double min_clearance, double min_wall_distance) {
  TrajectoryCheck c;
  auto fail = [&](const std::string& why) {
    if (c.ok) {
      c.ok = false;
      c.problem = why;
    }
  };
  const double W = scene.config.width, D = scene.config.depth, H = scene.config.height;
  for (size_t i = 0; i < trajectory.size(); ++i) {
    const Eigen::Vector3d p = trajectory[i].T_world_cam.translation();
    const double wall = std::min({p.x(), p.y(), W - p.x(), D - p.y(), H - p.z()});
    c.min_wall_distance = std::min(c.min_wall_distance, wall);
    c.min_height = std::min(c.min_height, p.z());
    c.max_height = std::max(c.max_height, p.z());
    for (const auto& f : scene.furniture)
      c.min_furniture_distance = std::min(c.min_furniture_distance, f.footprint_distance(p.head<2>()));
    if (wall < min_wall_distance) fail("frame " + std::to_string(i) + " is " + fmt(wall) + " m from a wall");
    if (p.z() < limits.min_height - 1e-6 || p.z() > limits.max_height + 1e-6)
      fail("frame " + std::to_string(i) + " at height " + fmt(p.z()));
    if (c.min_furniture_distance < min_clearance)
      fail("frame " + std::to_string(i) + " is within " + fmt(min_clearance) + " m of furniture");
    if (i > 0) {
      const SE3& a = trajectory[i - 1].T_world_cam;
      const SE3& b = trajectory[i].T_world_cam;
      const double step = (b.translation() - a.translation()).norm(), rot = (a.inverse() * b).rotation_angle() / kDeg;
      c.max_step = std::max(c.max_step, step);
      c.max_rotation_deg = std::max(c.max_rotation_deg, rot);
      if (step > limits.max_step + 1e-9) fail("step " + std::to_string(i) + " moves " + fmt(step) + " m");
      if (rot > limits.max_rotation_deg + 1e-9) fail("step " + std::to_string(i) + " turns " + fmt(rot) + " deg");
    }
    if (i > 0 && i + 1 < trajectory.size()) {
      const double dt = trajectory[i + 1].timestamp - trajectory[i].timestamp;
      const Eigen::Vector3d acc =
          (trajectory[i + 1].T_world_cam.translation() - 2 * p + trajectory[i - 1].T_world_cam.translation()) /
          (dt * dt);
      c.max_acceleration = std::max(c.max_acceleration, acc.norm());
    }
  }
  return c;
}

}  // namespace cslam::synth
