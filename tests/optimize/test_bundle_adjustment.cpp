#include <atomic>

#include <gtest/gtest.h>

#include "support/problems/optimize_problems.h"
#include "optimize/bundle_adjustment.h"

using namespace cslam;

namespace {

double total_chi2(const BaProblem& p, const std::vector<SE3>& poses, const std::vector<Eigen::Vector3d>& pts) {
  double s = 0;
  for (const auto& o : p.observations) {
    BaCamera c = p.cameras[o.camera];
    c.T_cam_world = poses[o.camera];
    s += ba_observation_chi2(c, pts[o.point], o);
  }
  return s;
}

BaProblem make_problem(std::mt19937& rng, std::vector<SE3>& true_poses, std::vector<Eigen::Vector3d>& true_points) {
  const auto k = problems::tum_like_intrinsics();
  BaProblem p;
  true_points = problems::random_points_in_front(200, rng);
  for (int c = 0; c < 5; ++c) {
    true_poses.push_back(problems::small_motion(0.03 * c, {0, 1, 0}, {0.1 * c, 0.0, 0.02 * c}));
    p.cameras.push_back({true_poses.back(), k, c < 2});  // gauge: two cameras fixed
  }
  std::normal_distribution<double> pix(0, 0.3), perturb(0, 0.02);
  for (size_t i = 0; i < true_points.size(); ++i) {
    p.points.push_back(true_points[i] + Eigen::Vector3d(perturb(rng), perturb(rng), perturb(rng)));
    for (int c = 0; c < 5; ++c) {
      const Eigen::Vector3d uvr = problems::project(k, true_poses[c], true_points[i]);
      BaObservation o;
      o.camera = c;
      o.point = int(i);
      o.uv = {uvr.x() + pix(rng), uvr.y() + pix(rng)};
      o.u_right = c % 2 ? uvr.z() + pix(rng) : -1;
      p.observations.push_back(o);
    }
  }
  for (int c = 2; c < 5; ++c)
    p.cameras[c].T_cam_world = problems::small_motion(0.01, {1, 0, 0}, {0.01, -0.01, 0.01}) * p.cameras[c].T_cam_world;
  return p;
}

}  // namespace

TEST(BundleAdjustment, ReducesReprojectionErrorAndRecoversPoses) {
  std::mt19937 rng(11);
  std::vector<SE3> truth;
  std::vector<Eigen::Vector3d> points;
  const BaProblem p = make_problem(rng, truth, points);
  std::vector<SE3> start;
  for (const auto& c : p.cameras) start.push_back(c.T_cam_world);
  const double before = total_chi2(p, start, p.points);
  const BaResult r = bundle_adjust(p);
  const double after = total_chi2(p, r.T_cam_world, r.points);
  EXPECT_LT(after, 0.05 * before);
  EXPECT_TRUE(r.converged);
  for (int c = 0; c < 2; ++c) EXPECT_LT((r.T_cam_world[c].translation() - start[c].translation()).norm(), 1e-12);
  for (int c = 2; c < 5; ++c) EXPECT_LT((r.T_cam_world[c].translation() - truth[c].translation()).norm(), 0.005);
}

TEST(BundleAdjustment, FlagsGrossOutliers) {
  std::mt19937 rng(5);
  std::vector<SE3> truth;
  std::vector<Eigen::Vector3d> points;
  BaProblem p = make_problem(rng, truth, points);
  for (size_t i = 0; i < p.observations.size(); i += 50) p.observations[i].uv += Eigen::Vector2d(40, -30);
  const BaResult r = bundle_adjust(p);
  for (size_t i = 0; i < p.observations.size(); i += 50) EXPECT_FALSE(r.inlier[i]) << i;
}

TEST(BundleAdjustment, AbortFlagStopsEarly) {
  std::mt19937 rng(3);
  std::vector<SE3> truth;
  std::vector<Eigen::Vector3d> points;
  const BaProblem p = make_problem(rng, truth, points);
  std::atomic<bool> abort{true};
  const BaResult r = bundle_adjust(p, {}, &abort);
  EXPECT_TRUE(r.aborted);
  EXPECT_LE(r.iterations, 2);
}
