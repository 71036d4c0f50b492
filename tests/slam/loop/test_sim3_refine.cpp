// refine_sim3 and the cost functors of the loop module (checked against numeric differentiation).
#include <array>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include <ceres/ceres.h>

#include "core/error.h"
#include "slam/loop/sim3_costs.h"
#include "slam/loop/sim3_projection.h"
#include "slam/loop/sim3_refine.h"
#include "loop_fixtures.h"

using namespace cslam;

namespace {

template <typename Functor, int kRes, int... kBlocks>
void compare_jacobians(const Functor& f, std::vector<double*> params) {
  ceres::AutoDiffCostFunction<Functor, kRes, kBlocks...> autodiff(new Functor(f));
  ceres::NumericDiffCostFunction<Functor, ceres::CENTRAL, kRes, kBlocks...> numeric(new Functor(f));
  const std::vector<int> sizes = {kBlocks...};
  std::vector<std::vector<double>> ja(sizes.size()), jn(sizes.size());
  std::vector<double*> pa, pn;
  for (size_t b = 0; b < sizes.size(); ++b) {
    ja[b].assign(kRes * sizes[b], 0);
    jn[b].assign(kRes * sizes[b], 0);
    pa.push_back(ja[b].data());
    pn.push_back(jn[b].data());
  }
  double ra[kRes], rn[kRes];
  ASSERT_TRUE(autodiff.Evaluate(params.data(), ra, pa.data()));
  ASSERT_TRUE(numeric.Evaluate(params.data(), rn, pn.data()));
  double max_abs = 0;
  for (int i = 0; i < kRes; ++i) EXPECT_NEAR(ra[i], rn[i], 1e-9);
  for (size_t b = 0; b < sizes.size(); ++b)
    for (size_t i = 0; i < ja[b].size(); ++i) {
      EXPECT_NEAR(ja[b][i], jn[b][i], 1e-5 * std::max(1.0, std::abs(jn[b][i]))) << "block " << b << " entry " << i;
      max_abs = std::max(max_abs, std::abs(ja[b][i]));
    }
  EXPECT_GT(max_abs, 1e-3);  // the Jacobian is not trivially zero
}

double sim3_error(const Sim3& a, const Sim3& b) {
  return a.rotation().angularDistance(b.rotation()) + (a.translation() - b.translation()).norm() +
         std::abs(std::log(a.scale() / b.scale()));
}

}  // namespace

TEST(LoopCosts, Sim3ReprojectionJacobiansMatchNumeric) {
  const auto k = test::loop_intrinsics();
  auto S = to_sim3_param(test::rotation_about(0.4, {0.3, 1, -0.2}, {0.2, -0.1, 0.3}, 1.3));
  const Sim3ReprojectionCost1 c1(k, {0.3, -0.2, 2.2}, {350.0, 240.0}, 1.0 / 1.2);
  compare_jacobians<Sim3ReprojectionCost1, 2, 6, 1>(c1, {S.pose.data(), &S.log_scale});
  const Sim3ReprojectionCost2 c2(k, {-0.4, 0.1, 2.8}, {300.0, 260.0}, 1.0);
  compare_jacobians<Sim3ReprojectionCost2, 2, 6, 1>(c2, {S.pose.data(), &S.log_scale});
}

TEST(LoopCosts, Sim3ReprojectionFromAnotherViewMatchesNumericAndGeometry) {
  const auto k = test::loop_intrinsics();
  const Sim3 S_true = test::rotation_about(0.4, {0.3, 1, -0.2}, {0.2, -0.1, 0.3}, 1.3);
  auto S = to_sim3_param(S_true);
  const SE3 T_view_1(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1, 0.1).normalized())),
                     Eigen::Vector3d(0.25, -0.05, 0.1));
  const Eigen::Vector3d p2(0.3, -0.2, 2.2);
  const Sim3ReprojectionCost1 c1(k, p2, {350.0, 240.0}, 1.0 / 1.2, T_view_1);
  compare_jacobians<Sim3ReprojectionCost1, 2, 6, 1>(c1, {S.pose.data(), &S.log_scale});
  // The residual is the projection of T_view_1 * S_12 * p2 in the viewing camera.
  const Eigen::Vector2d uv = test::project(k, T_view_1 * (S_true * p2));
  const Sim3ReprojectionCost1 exact(k, p2, uv, 1.0, T_view_1);
  double r[2];
  ASSERT_TRUE(exact(S.pose.data(), &S.log_scale, r));
  EXPECT_NEAR(r[0], 0.0, 1e-9);
  EXPECT_NEAR(r[1], 0.0, 1e-9);
  Sim3Correspondence m;
  m.p1 = S_true * p2;
  m.p2 = p2;
  m.uv1 = uv;
  m.uv2 = test::project(k, p2);
  m.T_view_1 = T_view_1;
  const auto e = sim3_match_chi2(S_true, m, k, k);
  EXPECT_NEAR(e.e1, 0.0, 1e-12);
  EXPECT_NEAR(e.e2, 0.0, 1e-12);
  m.T_view_1 = SE3();  // the same keypoint read as camera 1's own is far off
  EXPECT_GT(sim3_match_chi2(S_true, m, k, k).e1, 100.0);
}

// sim3_projection.h's residuals and analytic Jacobians against Ceres' autodiff of the functors
// (themselves checked against numeric differentiation above): angles from tiny to large, scales,
// observations from camera 1 itself and from other views. Below an angle of ~1e-7 Ceres rotates a
// point by its first-order formula p + w x p, whose derivative is off by O(|w|) relative (3e-8
// measured): there the bound is 1e-6 instead of 1e-8.
TEST(LoopCosts, AnalyticSim3JacobiansMatchAutodiff) {
  const auto k = test::loop_intrinsics();
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  int checked = 0;
  for (int trial = 0; trial < 60; ++trial) {
    const double angle = trial % 4 == 0 ? 1e-7 * (1 + U(rng)) : 1.2 * U(rng);
    const Sim3 S = test::rotation_about(angle, {U(rng), U(rng), 1.0}, {0.3 * U(rng), 0.3 * U(rng), 0.2 * U(rng)},
                                        std::exp(0.3 * U(rng)));
    Sim3Correspondence m;
    m.p2 = {0.8 * U(rng), 0.6 * U(rng), 2.5 + U(rng)};
    m.p1 = S * m.p2 + Eigen::Vector3d(0.02 * U(rng), 0.02 * U(rng), 0.02 * U(rng));
    m.uv1 = {320 + 200 * U(rng), 240 + 150 * U(rng)};
    m.uv2 = {320 + 200 * U(rng), 240 + 150 * U(rng)};
    if (trial % 2)
      m.T_view_1 =
          SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.2 * U(rng), Eigen::Vector3d(U(rng), 1, U(rng)).normalized())),
              Eigen::Vector3d(0.1 * U(rng), 0.1 * U(rng), 0.05 * U(rng)));
    const double w1 = 1.0 / (1.0 + 0.5 * (trial % 3)), w2 = 1.0 / 1.44;
    Sim3Param p = to_sim3_param(S);
    const std::array<double, 7> x = {p.pose[0], p.pose[1], p.pose[2], p.pose[3], p.pose[4], p.pose[5], p.log_scale};
    Sim3LinearizationPoint lp;
    lp.set(x.data());
    const double tolerance = angle < 1e-6 ? 1e-6 : 1e-8;
    auto compare = [&](const ceres::CostFunction& autodiff, const Eigen::Vector2d& r, const Matrix27d& J) {
      double ra[2], jpose[12], jscale[2];
      const double* params[2] = {p.pose.data(), &p.log_scale};
      double* jac[2] = {jpose, jscale};
      ASSERT_TRUE(autodiff.Evaluate(params, ra, jac));
      for (int i = 0; i < 2; ++i) {
        EXPECT_NEAR(r[i], ra[i], 1e-9 * std::max(1.0, std::abs(ra[i])));
        for (int c = 0; c < 6; ++c)
          EXPECT_NEAR(J(i, c), jpose[i * 6 + c], tolerance * std::max(1.0, std::abs(jpose[i * 6 + c])))
              << "trial " << trial << " row " << i << " col " << c;
        EXPECT_NEAR(J(i, 6), jscale[i], tolerance * std::max(1.0, std::abs(jscale[i]))) << "trial " << trial;
      }
      ++checked;
    };
    Matrix27d J;
    const Eigen::Vector2d r1 = sim3_residual_1(lp, m, k, w1, &J);
    EXPECT_LT((sim3_residual_1(lp, m, k, w1, nullptr) - r1).norm(), 1e-12);
    compare(ceres::AutoDiffCostFunction<Sim3ReprojectionCost1, 2, 6, 1>(
                new Sim3ReprojectionCost1(k, m.p2, m.uv1, w1, m.T_view_1)),
            r1, J);
    const Eigen::Vector2d r2 = sim3_residual_2(lp, m, k, w2, &J);
    compare(ceres::AutoDiffCostFunction<Sim3ReprojectionCost2, 2, 6, 1>(new Sim3ReprojectionCost2(k, m.p1, m.uv2, w2)),
            r2, J);
  }
  EXPECT_EQ(checked, 120);
}

TEST(LoopCosts, PoseGraphEdgeJacobiansMatchNumeric) {
  auto a = to_sim3_param(test::rotation_about(0.7, {0.1, 0.2, 1}, {1.0, 2.0, -0.5}, 1.1));
  auto b = to_sim3_param(test::rotation_about(1.1, {0.3, -0.2, 1}, {1.5, 2.4, -0.3}, 0.9));
  const Sim3 meas = test::rotation_about(0.35, {0, 0.1, 1}, {0.4, 0.3, 0.1}, 0.85);
  compare_jacobians<PoseGraphEdgeCost<7>, 7, 6, 1, 6, 1>(PoseGraphEdgeCost<7>(meas, 2.0),
                                                         {a.pose.data(), &a.log_scale, b.pose.data(), &b.log_scale});
  compare_jacobians<PoseGraphEdgeCost<6>, 6, 6, 1, 6, 1>(PoseGraphEdgeCost<6>(meas, 1.0),
                                                         {a.pose.data(), &a.log_scale, b.pose.data(), &b.log_scale});
}

TEST(LoopCosts, PoseGraphEdgeJacobiansAtExactMeasurement) {
  // At the optimum E = identity, where angle-axis uses its small-angle branch.
  const Sim3 A = test::rotation_about(0.7, {0.1, 0.2, 1}, {1.0, 2.0, -0.5}, 1.1);
  const Sim3 B = test::rotation_about(-1.2, {0.3, -0.2, 1}, {1.5, 2.4, -0.3}, 0.9);
  auto a = to_sim3_param(A), b = to_sim3_param(B);
  const Sim3 meas = A.inverse() * B;
  compare_jacobians<PoseGraphEdgeCost<7>, 7, 6, 1, 6, 1>(PoseGraphEdgeCost<7>(meas, 1.0),
                                                         {a.pose.data(), &a.log_scale, b.pose.data(), &b.log_scale});
}

TEST(LoopCosts, PoseGraphEdgeIsZeroForExactMeasurement) {
  const Sim3 a = test::rotation_about(0.7, {0.1, 0.2, 1}, {1.0, 2.0, -0.5}, 1.1);
  const Sim3 b = test::rotation_about(-2.9, {0.3, -0.2, 1}, {1.5, 2.4, -0.3}, 0.9);
  PoseGraphEdge e{0, 1, a.inverse() * b, 3.0};
  EXPECT_NEAR(pose_graph_edge_error(a, b, e, false), 0, 1e-20);
  e.S_from_to = e.S_from_to * test::rotation_about(0.01, {0, 0, 1}, {0, 0, 0});
  EXPECT_NEAR(pose_graph_edge_error(a, b, e, false), 3.0 * 0.01 * 0.01, 1e-8);  // weight * angle^2
}

TEST(LoopCosts, Sim3ParamRoundTrip) {
  const Sim3 S = test::rotation_about(2.8, {0.3, -0.4, 0.8}, {1, 2, 3}, 0.6);
  const auto p = to_sim3_param(S);
  EXPECT_LT(sim3_error(from_sim3_param(p.pose.data(), p.log_scale), S), 1e-12);
}

TEST(Sim3Refine, ReducesErrorAndFindsOutliers) {
  const auto k = test::loop_intrinsics();
  for (bool fix_scale : {true, false}) {
    const Sim3 truth = test::rotation_about(0.3, {0.2, 1.0, 0.1}, {0.3, -0.1, 0.2}, fix_scale ? 1.0 : 1.25);
    const auto set = test::make_matches(truth, 200, 0.5, 21);  // half of them wrong
    // Start from a perturbed estimate (about 1.5 deg, 5 cm, 3% scale off).
    const Sim3 start = truth * test::rotation_about(0.025, {1, -1, 0.5}, {0.04, -0.03, 0.02}, fix_scale ? 1.0 : 1.03);
    const auto r = refine_sim3(start, set.matches, k, k, fix_scale);
    EXPECT_LT(sim3_error(r.S_12, truth), 0.2 * sim3_error(start, truth)) << "fix_scale " << fix_scale;
    EXPECT_LT(test::rotation_error_deg(r.S_12, truth), 0.3);
    EXPECT_LT((r.S_12.translation() - truth.translation()).norm(), 0.02);
    if (fix_scale)
      EXPECT_DOUBLE_EQ(r.S_12.scale(), 1.0);
    else
      EXPECT_NEAR(r.S_12.scale(), 1.25, 0.015);
    EXPECT_LT(r.final_cost, 0.2 * r.initial_cost);  // Huber cost of the final inliers
    int wrong = 0, good = 0, n_true = 0;
    for (size_t i = 0; i < r.inlier.size(); ++i) {
      n_true += set.is_inlier[i];
      if (r.inlier[i]) (set.is_inlier[i] ? good : wrong)++;
    }
    EXPECT_EQ(good + wrong, r.num_inliers);
    EXPECT_GT(good, 0.9 * n_true);
    EXPECT_LE(wrong, 3);
  }
}

TEST(Sim3Refine, AfterRansacKeepsInliersAndDoesNotDegrade) {
  const auto k = test::loop_intrinsics();
  for (bool fix_scale : {true, false}) {
    const Sim3 truth = test::rotation_about(0.3, {0.2, 1.0, 0.1}, {0.3, -0.1, 0.2}, fix_scale ? 1.0 : 1.3);
    const auto set = test::make_matches(truth, 300, 0.5, 31);
    Sim3RansacConfig cfg;
    cfg.fix_scale = fix_scale;
    const auto ransac = sim3_ransac(set.matches, k, k, cfg);
    ASSERT_TRUE(ransac.success);
    const auto r = refine_sim3(ransac.S_12, set.matches, k, k, fix_scale);
    EXPECT_GE(r.num_inliers, int(0.95 * ransac.num_inliers)) << "fix_scale " << fix_scale;
    EXPECT_LT(test::rotation_error_deg(r.S_12, truth), 0.3);
    EXPECT_LT((r.S_12.translation() - truth.translation()).norm(), 0.02);
    EXPECT_LE(r.final_cost, r.initial_cost);
  }
}

TEST(Sim3Refine, ExactDataConvergesToTruth) {
  const auto k = test::loop_intrinsics();
  const Sim3 truth = test::rotation_about(-0.2, {1, 0.2, 0}, {0.1, 0.2, -0.1}, 0.8);
  const auto set = test::make_matches(truth, 60, 0.0, 5, 0.0, 0.0);
  const Sim3 start = truth * test::rotation_about(0.05, {0, 1, 0}, {0.05, 0, 0}, 1.05);
  const auto r = refine_sim3(start, set.matches, k, k, false);
  EXPECT_LT(sim3_error(r.S_12, truth), 1e-6);
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(r.num_inliers, 60);
  EXPECT_LT(r.final_cost, 1e-10);
}

// Window refinement: camera 1's own image is distorted (its keypoints read as if the camera had
// turned 1.5 degrees more: motion blur, rolling shutter), four other views of camera 1's map are
// not. Pooling their observations (each seen from its T_view_1) pulls the fit back to the truth.
TEST(Sim3Refine, ObservationsFromOtherViewsAverageOutOneImagesError) {
  const auto k = test::loop_intrinsics();
  const Sim3 truth = test::rotation_about(0.3, {0.1, 1, 0}, {0.2, 0.05, -0.1});
  const SE3 skew(Eigen::Quaterniond(Eigen::AngleAxisd(1.5 * M_PI / 180, Eigen::Vector3d::UnitY())),
                 Eigen::Vector3d::Zero());
  std::vector<Sim3Correspondence> own;
  for (auto m : test::make_matches(truth, 80, 0.0, 7, 0.3, 0.0).matches) {
    m.uv1 = test::project(k, skew * m.p1);  // the distorted image
    m.p1 = skew * m.p1;                     // and its depth back-projection
    own.push_back(m);
  }
  const auto alone = refine_sim3(truth, own, k, k, true);
  const double alone_deg = test::rotation_error_deg(alone.S_12, truth);
  EXPECT_GT(alone_deg, 1.0) << "camera 1's image alone should carry its error";
  std::vector<Sim3Correspondence> pooled = own;
  for (int v = 0; v < 4; ++v) {
    const SE3 T_view_1(
        Eigen::Quaterniond(Eigen::AngleAxisd(0.08 * (v - 1.5), Eigen::Vector3d(0.3, 1, 0.1).normalized())),
        Eigen::Vector3d(0.05 * (v - 1.5), 0.02 * v, 0.01));
    const Sim3 S_view = Sim3(T_view_1) * truth;
    for (auto m : test::make_matches(S_view, 80, 0.0, 100 + v, 0.3, 0.0).matches) {
      m.p1 = T_view_1.inverse() * m.p1;  // camera-1 coordinates
      m.T_view_1 = T_view_1;
      pooled.push_back(m);
    }
  }
  const auto window = refine_sim3(alone.S_12, pooled, k, k, true);
  const double window_deg = test::rotation_error_deg(window.S_12, truth);
  std::printf("rotation error: camera 1 alone %.3f deg, window of 5 views %.3f deg\n", alone_deg, window_deg);
  EXPECT_LT(window_deg, 0.5 * alone_deg) << "alone " << alone_deg << " deg, window " << window_deg << " deg";
  EXPECT_GE(window.num_inliers, 4 * 80 * 9 / 10);
}

// The hand-written solver against the Ceres reference: 48 problems (SE3 and Sim3, 8 to 400 matches,
// 0 to 60 % wrong, starts 0.5 to 6 degrees and up to 20 cm off, pooled views), the same iterates
// up to rounding: poses to 1e-9, the same inliers, the same costs and convergence flags.
TEST(Sim3Refine, TakesTheStepsOfTheCeresReference) {
  const auto k = test::loop_intrinsics();
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  double worst = 0;
  int with_outliers_removed = 0;
  for (int trial = 0; trial < 48; ++trial) {
    const bool fix_scale = trial % 2 == 0;
    const Sim3 truth =
        test::rotation_about(0.6 * U(rng), {U(rng) - 0.5, 1.0, U(rng) - 0.5},
                             {0.4 * U(rng), -0.2 * U(rng), 0.3 * U(rng)}, fix_scale ? 1.0 : 0.7 + 0.6 * U(rng));
    const int n = 8 + int(392 * U(rng) * U(rng));
    auto set = test::make_matches(truth, n, 0.6 * U(rng), std::uint64_t(100 + trial));
    if (trial % 3 == 0)
      for (std::size_t i = 0; i < set.matches.size(); i += 2) {  // half seen from another view of map 1
        const SE3 T_view_1(Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d(0.2, 1, 0).normalized())),
                           Eigen::Vector3d(0.05, 0.01, 0.0));
        set.matches[i].uv1 = test::project(k, T_view_1 * set.matches[i].p1);
        set.matches[i].T_view_1 = T_view_1;
      }
    const double off_deg = 0.5 + 5.5 * U(rng);
    const Sim3 start = truth * test::rotation_about(off_deg * M_PI / 180, {U(rng), U(rng), 1.0},
                                                    {0.2 * U(rng) - 0.1, 0.2 * U(rng) - 0.1, 0.2 * U(rng) - 0.1},
                                                    fix_scale ? 1.0 : 0.95 + 0.1 * U(rng));
    const auto own = refine_sim3(start, set.matches, k, k, fix_scale);
    const auto ref = refine_sim3_ceres(start, set.matches, k, k, fix_scale);
    const double e = sim3_error(own.S_12, ref.S_12);
    worst = std::max(worst, e);
    EXPECT_LT(e, 1e-9) << "trial " << trial << ": " << n << " matches, fix_scale " << fix_scale;
    EXPECT_EQ(own.inlier, ref.inlier) << "trial " << trial;
    EXPECT_EQ(own.num_inliers, ref.num_inliers) << "trial " << trial;
    EXPECT_EQ(own.converged, ref.converged) << "trial " << trial;
    EXPECT_NEAR(own.initial_cost, ref.initial_cost, 1e-9 * std::max(1.0, ref.initial_cost)) << "trial " << trial;
    EXPECT_NEAR(own.final_cost, ref.final_cost, 1e-9 * std::max(1.0, ref.final_cost)) << "trial " << trial;
    if (fix_scale) {
      EXPECT_EQ(own.S_12.scale(), start.scale());
    }
    with_outliers_removed += own.num_inliers < n;
  }
  std::printf("largest difference to the Ceres reference: %.2e\n", worst);
  EXPECT_GT(with_outliers_removed, 20);  // the problems exercise the outlier stage
}

TEST(Sim3Refine, TooFewMatchesAndBadChi2) {
  const auto k = test::loop_intrinsics();
  const Sim3 S = test::rotation_about(0.1, {0, 1, 0}, {0, 0, 0});
  const auto r = refine_sim3(S, {}, k, k, true);
  EXPECT_EQ(r.num_inliers, 0);
  EXPECT_LT(sim3_error(r.S_12, S), 1e-15);
  EXPECT_THROW(refine_sim3(S, {}, k, k, true, 0.0), ConfigError);
}
