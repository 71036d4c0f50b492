#pragma once
// Synthetic optimisation problems (points in front of cameras, exact projections, outliers) for the
// optimisers' unit tests and cslam-bench-optimize.
#include <random>
#include <vector>

#include "geometry/se3.h"
#include "optimize/bundle_adjustment.h"
#include "optimize/pose_optimizer.h"
#include "optimize/reprojection_cost.h"

namespace cslam::problems {

inline StereoIntrinsics tum_like_intrinsics() { return {517.3, 516.5, 318.6, 255.3, 40.0}; }

inline std::vector<Eigen::Vector3d> random_points_in_front(int n, std::mt19937& rng) {
  std::uniform_real_distribution<double> xy(-1.5, 1.5), z(1.0, 4.0);
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < n; ++i) pts.emplace_back(xy(rng), xy(rng), z(rng));
  return pts;
}

inline Eigen::Vector3d project(const StereoIntrinsics& k, const SE3& T_cam_world, const Eigen::Vector3d& pw) {
  const Eigen::Vector3d p = T_cam_world * pw;
  const double u = k.fx * p.x() / p.z() + k.cx;
  return {u, k.fy * p.y() / p.z() + k.cy, u - k.bf / p.z()};
}

inline SE3 small_motion(double angle, const Eigen::Vector3d& axis, const Eigen::Vector3d& t) {
  return SE3(Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized())), t);
}

// A tracking-like pose-only problem: n keypoints spread over a 640x480 image at 0.5-6 m, pyramid
// levels 0-7 (sigma 1.2^level px), a fraction with depth ("stereo"), a fraction of gross
// outliers, and a start pose a few degrees / centimetres off (the motion model's error).
struct PoseProblem {
  SE3 truth, start;
  std::vector<PoseObservation> obs;
  std::vector<char> is_outlier;
};

inline PoseProblem random_pose_problem(std::mt19937& rng, int n, double outlier_fraction, double stereo_fraction) {
  const auto k = tum_like_intrinsics();
  std::uniform_real_distribution<double> U(0, 1), S(-1, 1);
  std::normal_distribution<double> N(0, 1);
  PoseProblem p;
  p.truth = small_motion(0.4 * S(rng), {S(rng), S(rng), S(rng) + 2}, {S(rng), S(rng), S(rng)});
  const SE3 T_world_cam = p.truth.inverse();
  for (int i = 0; i < n; ++i) {
    const double u = 640 * U(rng), v = 480 * U(rng), z = 0.5 + 5.5 * U(rng);
    const Eigen::Vector3d pc((u - k.cx) * z / k.fx, (v - k.cy) * z / k.fy, z);
    const int level = int(8 * U(rng) * U(rng));  // more keypoints at the fine levels
    const double sigma = std::pow(1.2, level);
    PoseObservation o;
    o.p_world = T_world_cam * pc;
    o.inv_sigma2 = 1.0 / (sigma * sigma);
    const bool outlier = U(rng) < outlier_fraction;
    const bool stereo = U(rng) < stereo_fraction;
    if (outlier) {
      o.uv = {640 * U(rng), 480 * U(rng)};
      if (stereo) o.u_right = o.uv.x() - 40.0 / (0.5 + 5.5 * U(rng));
    } else {
      o.uv = Eigen::Vector2d(u, v) + 0.7 * sigma * Eigen::Vector2d(N(rng), N(rng));
      if (stereo) o.u_right = u - k.bf / z + 0.7 * sigma * N(rng);
    }
    p.obs.push_back(o);
    p.is_outlier.push_back(outlier);
  }
  p.start = small_motion(0.03 + 0.03 * U(rng), {S(rng), S(rng), S(rng) + 0.1},
                         0.05 * Eigen::Vector3d(S(rng), S(rng), S(rng))) *
            p.truth;
  return p;
}

// A local-BA-like problem: keyframes along a 3D arc looking at a scene 1.5-7 m away, each point
// observed by every keyframe that sees it in the image with probability `visibility`; the free
// keyframes come first (as local BA orders them), the fixed ones were taken before them. Poses
// and points start a little off the truth; a fraction of observations are gross outliers.
struct BaSynthetic {
  BaProblem problem;
  std::vector<SE3> true_poses;
  std::vector<Eigen::Vector3d> true_points;
  std::vector<char> is_outlier;  // per observation
};

inline BaSynthetic random_ba_problem(std::mt19937& rng, int free_cams, int fixed_cams, int num_points,
                                     double outlier_fraction, double stereo_fraction, double visibility = 0.6) {
  const auto k = tum_like_intrinsics();
  std::uniform_real_distribution<double> U(0, 1), S(-1, 1);
  std::normal_distribution<double> N(0, 1);
  BaSynthetic b;
  const int n = free_cams + fixed_cams;
  std::vector<SE3> truth(n);
  for (int i = 0; i < n; ++i) {  // i-th keyframe in time; the fixed ones are the oldest
    const double a = 0.04 * i;
    const SE3 T_world_cam(Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitY()) *
                                             Eigen::AngleAxisd(0.05 * std::sin(i), Eigen::Vector3d::UnitX())),
                          Eigen::Vector3d(0.12 * i, 0.03 * std::sin(0.7 * i), 0.02 * i));
    truth[i] = T_world_cam.inverse();
  }
  for (int c = 0; c < n; ++c) {
    const int time = c < free_cams ? fixed_cams + c : c - free_cams;
    b.true_poses.push_back(truth[time]);
    BaCamera cam;
    cam.T_cam_world = truth[time];
    cam.intrinsics = k;
    cam.fixed = c >= free_cams;
    b.problem.cameras.push_back(cam);
  }
  while (int(b.true_points.size()) < num_points) {
    // A point in front of a random keyframe.
    const SE3& ref = truth[int(U(rng) * n) % n];
    const double z = 1.5 + 5.5 * U(rng);
    const Eigen::Vector3d pc((640 * U(rng) - k.cx) * z / k.fx, (480 * U(rng) - k.cy) * z / k.fy, z);
    const Eigen::Vector3d pw = ref.inverse() * pc;
    std::vector<BaObservation> obs;
    std::vector<char> outl;
    bool seen_by_free = false;
    for (int c = 0; c < n; ++c) {
      const Eigen::Vector3d p = b.true_poses[c] * pw;
      if (p.z() < 0.3) continue;
      const Eigen::Vector3d uvr = project(k, b.true_poses[c], pw);
      if (uvr.x() < 0 || uvr.x() >= 640 || uvr.y() < 0 || uvr.y() >= 480 || U(rng) > visibility) continue;
      const int level = int(8 * U(rng) * U(rng));
      const double sigma = std::pow(1.2, level);
      BaObservation o;
      o.camera = c;
      o.point = int(b.true_points.size());
      o.inv_sigma2 = 1.0 / (sigma * sigma);
      const bool stereo = U(rng) < stereo_fraction, outlier = U(rng) < outlier_fraction;
      if (outlier) {
        o.uv = {640 * U(rng), 480 * U(rng)};
        if (stereo) o.u_right = o.uv.x() - k.bf / (1.5 + 5.5 * U(rng));
      } else {
        o.uv = uvr.head<2>() + 0.7 * sigma * Eigen::Vector2d(N(rng), N(rng));
        if (stereo) o.u_right = uvr.z() + 0.7 * sigma * N(rng);
      }
      seen_by_free = seen_by_free || c < free_cams;
      obs.push_back(o);
      outl.push_back(outlier);
    }
    if (obs.size() < 2 || !seen_by_free) continue;
    b.true_points.push_back(pw);
    b.problem.points.push_back(pw + 0.03 * Eigen::Vector3d(N(rng), N(rng), N(rng)));
    for (size_t i = 0; i < obs.size(); ++i) {
      b.problem.observations.push_back(obs[i]);
      b.is_outlier.push_back(outl[i]);
    }
  }
  for (int c = 0; c < free_cams; ++c)
    b.problem.cameras[c].T_cam_world =
        small_motion(0.01 * U(rng), {S(rng), S(rng), S(rng) + 0.1}, 0.02 * Eigen::Vector3d(S(rng), S(rng), S(rng))) *
        b.problem.cameras[c].T_cam_world;
  return b;
}

}  // namespace cslam::problems
