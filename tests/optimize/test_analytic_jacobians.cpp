// The fast optimisers' analytic derivatives checked against central differences of the Ceres
// reference residual (ReprojectionCost, same parameters).
#include <ceres/loss_function.h>
#include <gtest/gtest.h>

#include "support/problems/optimize_problems.h"
#include "optimize/pose_param.h"
#include "optimize/se3_projection.h"

using namespace cslam;

namespace {

// Unwhitened (u, v, u_right) minus zero observation, from the reference functor.
Eigen::Vector3d reference_uvr(const StereoIntrinsics& k, const double* pose, const double* point) {
  const ReprojectionCost<3> cost(k, 0.0, 0.0, 0.0, 1.0);
  Eigen::Vector3d r;
  cost(pose, point, r.data());
  return r;
}

}  // namespace

TEST(AnalyticJacobians, PoseAndPointJacobiansMatchNumericDifferences) {
  const auto k = problems::tum_like_intrinsics();
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> U(-1, 1);
  int checked = 0;
  for (int trial = 0; trial < 40; ++trial) {
    // Rotations from tiny (the small-angle branch of Jr) to large ones.
    const double angle = trial < 5 ? 1e-6 * trial : 2.5 * U(rng);
    const SE3 T =
        problems::small_motion(angle, {U(rng), U(rng), 1 + U(rng)}, {0.3 * U(rng), 0.3 * U(rng), 0.3 * U(rng)});
    const Eigen::Vector3d pw = T.inverse() * Eigen::Vector3d(1.5 * U(rng), 1.2 * U(rng), 2.5 + 1.5 * U(rng));
    std::array<double, 6> x = to_param(T);
    PoseLinearizationPoint lp;
    lp.set(x.data());
    Eigen::Vector3d uvr;
    Matrix36d J_pose;
    Eigen::Matrix3d J_point;
    project_with_jacobians(k, lp, pw, uvr, J_pose, J_point);
    EXPECT_LT((uvr - reference_uvr(k, x.data(), pw.data())).norm(), 1e-9);
    // The pose-only solver's factored form of the same Jacobian.
    const Eigen::Vector3d pc = lp.R * pw + lp.t;
    const Matrix36d factored = camera_motion_jacobian(k, pc, 1.0 / pc.z()) * param_map(lp);
    EXPECT_LT((factored - J_pose).norm(), 1e-10 * J_pose.norm()) << "trial " << trial;
    const double h = 1e-6;
    for (int j = 0; j < 6; ++j) {
      std::array<double, 6> xp = x, xm = x;
      xp[j] += h;
      xm[j] -= h;
      const Eigen::Vector3d numeric =
          (reference_uvr(k, xp.data(), pw.data()) - reference_uvr(k, xm.data(), pw.data())) / (2 * h);
      for (int r = 0; r < 3; ++r, ++checked)
        EXPECT_NEAR(J_pose(r, j), numeric(r), 1e-5 * std::max(1.0, std::abs(numeric(r))))
            << "trial " << trial << " row " << r << " col " << j;
    }
    for (int j = 0; j < 3; ++j) {
      Eigen::Vector3d pp = pw, pm = pw;
      pp(j) += h;
      pm(j) -= h;
      const Eigen::Vector3d numeric =
          (reference_uvr(k, x.data(), pp.data()) - reference_uvr(k, x.data(), pm.data())) / (2 * h);
      for (int r = 0; r < 3; ++r, ++checked)
        EXPECT_NEAR(J_point(r, j), numeric(r), 1e-5 * std::max(1.0, std::abs(numeric(r))))
            << "trial " << trial << " row " << r << " col " << j;
    }
  }
  EXPECT_EQ(checked, 40 * 27);
}

TEST(AnalyticJacobians, RightJacobianMatchesNumericExp) {
  // R(w + d) ~ R(w) Exp(Jr(w) d): compare Jr(w) d against Log(R(w)^T R(w + d)) / |d|.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1, 1);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d w = (trial < 3 ? 1e-7 : 2.0) * Eigen::Vector3d(U(rng), U(rng), U(rng));
    const Eigen::Matrix3d Jr = so3_right_jacobian(w);
    for (int j = 0; j < 3; ++j) {
      const double h = 1e-6;
      Eigen::Vector3d wp = w, wm = w;
      wp(j) += h;
      wm(j) -= h;
      const Eigen::Matrix3d R =
          Eigen::AngleAxisd(w.norm(), w.norm() > 0 ? w.normalized() : Eigen::Vector3d::UnitX()).toRotationMatrix();
      auto rot = [](const Eigen::Vector3d& v) {
        return Eigen::AngleAxisd(v.norm(), v.norm() > 0 ? v.normalized() : Eigen::Vector3d::UnitX()).toRotationMatrix();
      };
      const Eigen::AngleAxisd dp(R.transpose() * rot(wp)), dm(R.transpose() * rot(wm));
      const Eigen::Vector3d numeric = (dp.angle() * dp.axis() - dm.angle() * dm.axis()) / (2 * h);
      for (int r = 0; r < 3; ++r) EXPECT_NEAR(Jr(r, j), numeric(r), 1e-6) << "trial " << trial;
    }
  }
}

TEST(AnalyticJacobians, HuberMatchesCeresDefinition) {
  // rho(s) = s for s <= d^2, 2 d sqrt(s) - d^2 beyond; weight = rho'(s), continuous at d^2.
  const double d = std::sqrt(5.991);
  ceres::HuberLoss loss(d);
  for (double s : {0.5, 3.0, 5.991, 6.5, 100.0, 1e4}) {
    double rho[3];
    loss.Evaluate(s, rho);
    const HuberValue h = huber(s, d, d * d);
    EXPECT_NEAR(h.rho, rho[0], 1e-12 * std::max(1.0, rho[0])) << s;
    EXPECT_NEAR(h.weight, rho[1], 1e-12) << s;
  }
}
