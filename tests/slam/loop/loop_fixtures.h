#pragma once
// Synthetic fixtures for loop tests: 3D-3D matches between two RGB-D cameras related by a known
// similarity (with keypoint/depth noise and wrong matches), and drifted pose chains around a circle.
#include <cmath>
#include <random>
#include <vector>

#include "slam/loop/pose_graph.h"
#include "slam/loop/sim3_ransac.h"

namespace cslam::test {

inline StereoIntrinsics loop_intrinsics() { return {517.3, 516.5, 318.6, 255.3, 40.0}; }

inline Eigen::Vector2d project(const StereoIntrinsics& k, const Eigen::Vector3d& p) {
  return {k.fx * p.x() / p.z() + k.cx, k.fy * p.y() / p.z() + k.cy};
}
inline Eigen::Vector3d unproject(const StereoIntrinsics& k, const Eigen::Vector2d& uv, double z) {
  return {(uv.x() - k.cx) / k.fx * z, (uv.y() - k.cy) / k.fy * z, z};
}
inline bool in_image(const Eigen::Vector2d& uv) { return uv.x() >= 0 && uv.y() >= 0 && uv.x() < 640 && uv.y() < 480; }

inline Sim3 rotation_about(double angle, const Eigen::Vector3d& axis, const Eigen::Vector3d& t, double s = 1.0) {
  return Sim3(Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized())), t, s);
}

struct MatchSet {
  std::vector<Sim3Correspondence> matches;
  std::vector<char> is_inlier;  // ground truth: a correct match
};

// n matches seen by both cameras (p1 = S_12 * p2), a fraction of them replaced by wrong matches.
// Keypoints get pixel_noise (px), depths depth_noise * z^2 (m); 3D points are back-projected
// from the noisy keypoints and depths, as an RGB-D front-end does. Camera 1 sees metres scaled by
// S_12.scale() (as a monocular map with another scale would).
inline MatchSet make_matches(const Sim3& S_12, int n, double outlier_ratio, std::uint64_t seed,
                             double pixel_noise = 0.5, double depth_noise = 0.002) {
  const auto k = loop_intrinsics();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::normal_distribution<double> N(0.0, 1.0);
  MatchSet set;
  while (int(set.matches.size()) < n) {
    const Eigen::Vector2d uv2_true(20 + 600 * U(rng), 20 + 440 * U(rng));
    const double z2 = 1.0 + 3.0 * U(rng);
    const Eigen::Vector3d p2_true = unproject(k, uv2_true, z2);
    const Eigen::Vector3d p1_true = S_12 * p2_true;
    if (p1_true.z() < 0.5) continue;
    const Eigen::Vector2d uv1_true = project(k, p1_true);
    if (!in_image(uv1_true)) continue;
    Sim3Correspondence m;
    m.uv1 = uv1_true + pixel_noise * Eigen::Vector2d(N(rng), N(rng));
    m.uv2 = uv2_true + pixel_noise * Eigen::Vector2d(N(rng), N(rng));
    const double s = S_12.scale();
    m.p1 = unproject(k, m.uv1, p1_true.z() + s * depth_noise * (p1_true.z() / s) * (p1_true.z() / s) * N(rng));
    m.p2 = unproject(k, m.uv2, z2 + depth_noise * z2 * z2 * N(rng));
    const bool outlier = U(rng) < outlier_ratio;
    if (outlier) {  // a wrong match: camera 1 side is some other point of its image
      m.uv1 = Eigen::Vector2d(20 + 600 * U(rng), 20 + 440 * U(rng));
      m.p1 = unproject(k, m.uv1, s * (1.0 + 3.0 * U(rng)));
    }
    set.matches.push_back(m);
    set.is_inlier.push_back(!outlier);
  }
  return set;
}

inline double rotation_error_deg(const Sim3& a, const Sim3& b) {
  return a.rotation().angularDistance(b.rotation()) * 180.0 / M_PI;
}

// A closed loop around a circle of radius r: ground truth camera-to-world poses (scale 1).
inline std::vector<Sim3> circle_poses(int n, double r) {
  std::vector<Sim3> poses;
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * M_PI * i / n;
    poses.push_back(rotation_about(a + M_PI / 2, Eigen::Vector3d::UnitZ(),
                                   Eigen::Vector3d(r * std::cos(a), r * std::sin(a), 0.3 * std::sin(2 * a))));
  }
  return poses;
}

struct DriftedGraph {
  std::vector<Sim3> truth;
  std::vector<PoseGraphNode> nodes;  // poses integrated from the drifted odometry, node 0 fixed
  std::vector<PoseGraphEdge> edges;  // odometry i -> i+1 (drifted), then one loop edge n-1 -> 0 (true)
};

// Odometry with a systematic rotation bias (yaw_bias rad per step), small random noise and scale
// drift: edge i's translation is measured in units that shrink by scale_drift per step (as in a
// monocular map), so the integrated chain grows by scale_drift^i. Odometry edges are rigid (scale
// 1). The loop edge n-1 -> 0 is what a Sim3 loop detection measures: the true relative pose
// expressed in node n-1's units, i.e. translation and scale multiplied by scale_drift^(n-2).
inline DriftedGraph drifted_circle(int n, double yaw_bias, double scale_drift, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> N(0.0, 1.0);
  DriftedGraph g;
  g.truth = circle_poses(n, 5.0);
  g.nodes.push_back({g.truth[0], true});
  double units = 1.0;
  for (int i = 0; i + 1 < n; ++i) {
    if (i > 0) units *= scale_drift;
    const Sim3 rel = g.truth[i].inverse() * g.truth[i + 1];
    const Sim3 noise = rotation_about(yaw_bias + 0.001 * N(rng), Eigen::Vector3d(0.1 * N(rng), 0.1 * N(rng), 1.0),
                                      Eigen::Vector3d(0.003 * N(rng), 0.003 * N(rng), 0.003 * N(rng)));
    const Sim3 rigid = rel * noise;
    const Sim3 odo(rigid.rotation(), units * rigid.translation(), 1.0);
    g.edges.push_back({i, i + 1, odo, 1.0});
    g.nodes.push_back({g.nodes.back().S_world_node * odo, false});
  }
  const Sim3 loop = g.truth[n - 1].inverse() * g.truth[0];
  g.edges.push_back({n - 1, 0, Sim3(loop.rotation(), units * loop.translation(), units), 1.0});
  return g;
}

inline double max_position_error(const std::vector<Sim3>& est, const std::vector<Sim3>& truth) {
  double m = 0;
  for (size_t i = 0; i < est.size(); ++i) m = std::max(m, (est[i].translation() - truth[i].translation()).norm());
  return m;
}

}  // namespace cslam::test
