// The Schur-complement BA against the Ceres reference on randomized local-BA-like problems
// (mono and stereo observations, outliers, fixed keyframes): same inlier sets, same poses and
// points up to rounding (points along the directions the cost constrains), same costs and
// iteration counts; bit-identical output on repeated calls.
#include <gtest/gtest.h>

#include "support/problems/optimize_problems.h"
#include "optimize/bundle_adjustment.h"
#include "optimize/ceres_reference.h"
#include "optimize/pose_param.h"
#include "optimize/schur_ba.h"
#include "optimize/se3_projection.h"
#include "optimize/sparse_ba.h"

using namespace cslam;

namespace {

struct Case {
  int free_cams, fixed_cams, points;
  double outliers, stereo;
};

bool borderline(const BaProblem& p, const BaResult& a, const BaResult& b, size_t i, const BaConfig& cfg) {
  const BaObservation& o = p.observations[i];
  const double thr = o.u_right >= 0 ? cfg.chi2_stereo : cfg.chi2_mono;
  for (const BaResult* r : {&a, &b}) {
    BaCamera c = p.cameras[o.camera];
    c.T_cam_world = r->T_cam_world[o.camera];
    if (std::abs(ba_observation_chi2(c, r->points[o.point], o) - thr) < 1e-4 * thr) return true;
  }
  return false;
}

// Information (J^T W J) of each point from its inlier observations at a solution. A point seen
// by one monocular inlier is free along its ray: only the directions the cost sees are compared.
std::vector<Eigen::Matrix3d> point_information(const BaProblem& p, const BaResult& r) {
  std::vector<Eigen::Matrix3d> info(p.points.size(), Eigen::Matrix3d::Zero());
  for (size_t i = 0; i < p.observations.size(); ++i) {
    if (!r.inlier[i]) continue;
    const BaObservation& o = p.observations[i];
    const auto x = to_param(r.T_cam_world[o.camera]);
    PoseLinearizationPoint lp;
    lp.set(x.data());
    Eigen::Vector3d uvr;
    Matrix36d Jc;
    Eigen::Matrix3d Jp;
    project_with_jacobians(p.cameras[o.camera].intrinsics, lp, r.points[o.point], uvr, Jc, Jp);
    if (o.u_right < 0) Jp.row(2).setZero();
    info[o.point] += o.inv_sigma2 * Jp.transpose() * Jp;
  }
  return info;
}

using Solver = BaResult (*)(const BaProblem&, const BaConfig&, const std::atomic<bool>*);

const std::vector<Case> kLocalBaCases = {{3, 2, 80, 0.0, 1.0},
                                         {6, 4, 300, 0.05, 0.8},
                                         {10, 5, 600, 0.1, 0.5},
                                         {20, 8, 1500, 0.05, 0.9},
                                         {8, 2, 400, 0.1, 0.3}};

void compare_with_reference(Solver solver, const std::vector<Case>& cases = kLocalBaCases, int reps = 3) {
  BaConfig cfg;
  cfg.min_step_decrease = 0;  // step for step with Ceres: its termination rules alone
  std::mt19937 rng(77);
  double worst_pose = 0, worst_point = 0;
  int borderline_count = 0;
  for (const Case& c : cases) {
    for (int rep = 0; rep < reps; ++rep) {
      const problems::BaSynthetic s =
          problems::random_ba_problem(rng, c.free_cams, c.fixed_cams, c.points, c.outliers, c.stereo);
      const BaProblem& p = s.problem;
      const BaResult fast = solver(p, cfg, nullptr);
      const BaResult ref = bundle_adjust_ceres(p, cfg);
      ASSERT_EQ(fast.T_cam_world.size(), ref.T_cam_world.size());
      ASSERT_EQ(fast.points.size(), ref.points.size());
      for (size_t k = 0; k < p.cameras.size(); ++k) {
        const double d = std::max((fast.T_cam_world[k].translation() - ref.T_cam_world[k].translation()).norm(),
                                  fast.T_cam_world[k].rotation().angularDistance(ref.T_cam_world[k].rotation()));
        worst_pose = std::max(worst_pose, d);
        EXPECT_LT(d, 1e-7) << "camera " << k << " case " << c.free_cams << " rep " << rep;
        if (p.cameras[k].fixed) {
          EXPECT_LT((fast.T_cam_world[k].translation() - p.cameras[k].T_cam_world.translation()).norm(), 1e-15);
        }
      }
      const auto info = point_information(p, ref);
      for (size_t k = 0; k < p.points.size(); ++k) {
        const Eigen::Vector3d d = fast.points[k] - ref.points[k];
        const double whitened_px = std::sqrt(std::max(0.0, d.dot(info[k] * d)));  // change of the point's reprojections
        worst_point = std::max(worst_point, whitened_px);
        EXPECT_LT(whitened_px, 1e-5) << "point " << k << " case " << c.free_cams << " rep " << rep;
      }
      int differing = 0;
      for (size_t i = 0; i < p.observations.size(); ++i) {
        if (fast.inlier[i] == ref.inlier[i]) continue;
        if (borderline(p, fast, ref, i, cfg))
          ++borderline_count;
        else
          ++differing;
      }
      EXPECT_EQ(differing, 0) << "case " << c.free_cams << " rep " << rep;
      EXPECT_NEAR(fast.initial_cost, ref.initial_cost, 1e-9 * ref.initial_cost);
      EXPECT_NEAR(fast.final_cost, ref.final_cost, 1e-6 * std::max(1.0, ref.final_cost));
      EXPECT_EQ(fast.iterations, ref.iterations) << "case " << c.free_cams << " rep " << rep;
      EXPECT_EQ(fast.converged, ref.converged);
      EXPECT_FALSE(fast.aborted);
      // And the solution is good: free keyframes back near the truth.
      for (int k = 0; k < c.free_cams; ++k)
        EXPECT_LT((fast.T_cam_world[k].translation() - s.true_poses[k].translation()).norm(), 0.01);
    }
  }
  EXPECT_LE(borderline_count, 2);
  std::printf("worst pose difference %.3g, point difference %.3g whitened px, borderline flips %d\n", worst_pose,
              worst_point, borderline_count);
}

BaResult sparse_solver(const BaProblem& p, const BaConfig& c, const std::atomic<bool>* a) {
  return bundle_adjust_sparse(p, c, a);
}
BaResult schur_solver(const BaProblem& p, const BaConfig& c, const std::atomic<bool>* a) {
  return bundle_adjust(p, c, a);
}

}  // namespace

TEST(BundleAdjustmentVsCeres, SchurSolverMatchesReference) { compare_with_reference(schur_solver); }

// Beyond kMaxDenseSchurCameras free keyframes: the block-sparse reduced camera system (global and
// group BAs) over a trajectory's banded covisibility, with many or one fixed keyframe.
TEST(BundleAdjustmentVsCeres, BlockSparseSchurSolverMatchesReference) {
  const std::vector<Case> cases = {{130, 6, 5000, 0.05, 0.85}, {110, 1, 4000, 0.1, 0.5}};
  for (const Case& c : cases) ASSERT_GT(c.free_cams, kMaxDenseSchurCameras);
  compare_with_reference(schur_solver, cases, 1);
}

// Ceres' sparse Schur path (analytic Jacobians, explicit ordering, problem built once).
TEST(BundleAdjustmentVsCeres, SparseSolverMatchesReference) { compare_with_reference(sparse_solver); }

TEST(BundleAdjustmentVsCeres, RepeatedCallsAreBitIdentical) {
  std::mt19937 rng(8);
  const problems::BaSynthetic s = problems::random_ba_problem(rng, 10, 4, 500, 0.1, 0.7);
  const BaResult a = bundle_adjust(s.problem), b = bundle_adjust(s.problem);
  ASSERT_EQ(a.points.size(), b.points.size());
  for (size_t k = 0; k < a.T_cam_world.size(); ++k) {
    EXPECT_EQ(a.T_cam_world[k].rotation().coeffs(), b.T_cam_world[k].rotation().coeffs());
    EXPECT_EQ(a.T_cam_world[k].translation(), b.T_cam_world[k].translation());
  }
  for (size_t k = 0; k < a.points.size(); ++k) EXPECT_EQ(a.points[k], b.points[k]);
  EXPECT_EQ(a.inlier, b.inlier);
  EXPECT_EQ(a.final_cost, b.final_cost);
}

TEST(BundleAdjustmentVsCeres, AbortBeforeTheFirstStepLeavesTheProblemUnchanged) {
  std::mt19937 rng(9);
  const problems::BaSynthetic s = problems::random_ba_problem(rng, 5, 2, 200, 0.05, 0.7);
  std::atomic<bool> abort{true};
  const BaResult a = bundle_adjust(s.problem, {}, &abort);
  const BaResult r = bundle_adjust_ceres(s.problem, {}, &abort);
  EXPECT_TRUE(a.aborted);
  EXPECT_FALSE(a.converged);
  EXPECT_EQ(a.iterations, r.iterations);
  for (size_t k = 0; k < s.problem.points.size(); ++k) EXPECT_LT((a.points[k] - s.problem.points[k]).norm(), 1e-15);
  EXPECT_EQ(a.inlier, r.inlier);
}

TEST(BundleAdjustmentVsCeres, AllKeyframesFixedAndUnobservedPoints) {
  // Only points move (an empty reduced camera system); a point without observations stays put.
  std::mt19937 rng(12);
  problems::BaSynthetic s = problems::random_ba_problem(rng, 4, 2, 150, 0.05, 0.8);
  for (auto& c : s.problem.cameras) c.fixed = true;
  s.problem.points.push_back({0.5, -0.5, 3.0});
  const BaResult fast = bundle_adjust(s.problem), ref = bundle_adjust_ceres(s.problem);
  EXPECT_TRUE(fast.converged);
  EXPECT_EQ(fast.iterations, ref.iterations);
  EXPECT_EQ(fast.inlier, ref.inlier);
  const auto info = point_information(s.problem, ref);
  for (size_t k = 0; k + 1 < s.problem.points.size(); ++k) {
    const Eigen::Vector3d d = fast.points[k] - ref.points[k];
    EXPECT_LT(std::sqrt(std::max(0.0, d.dot(info[k] * d))), 1e-5) << k;
  }
  EXPECT_EQ(fast.points.back(), s.problem.points.back());
  for (size_t c = 0; c < s.problem.cameras.size(); ++c)
    EXPECT_EQ(fast.T_cam_world[c].translation(), ref.T_cam_world[c].translation());
}

// The default early end (a stage stops after a step that lowered its cost by <= 1e-4 of it):
// fewer iterations, the same inliers and a solution that the remaining iterations would hardly move.
TEST(BundleAdjustmentVsCeres, EarlyEndAfterATinyStepStaysAtTheFullSolution) {
  const Case cases[] = {{6, 4, 300, 0.05, 0.8}, {10, 5, 600, 0.1, 0.5}, {20, 8, 1500, 0.05, 0.9}};
  std::mt19937 rng(91);
  BaConfig full;
  full.min_step_decrease = 0;
  const BaConfig early;
  ASSERT_GT(early.min_step_decrease, 0.0);
  int iterations_full = 0, iterations_early = 0;
  for (const Case& c : cases)
    for (int rep = 0; rep < 3; ++rep) {
      const problems::BaSynthetic s =
          problems::random_ba_problem(rng, c.free_cams, c.fixed_cams, c.points, c.outliers, c.stereo);
      const BaResult a = bundle_adjust(s.problem, early), b = bundle_adjust(s.problem, full);
      iterations_early += a.iterations;
      iterations_full += b.iterations;
      EXPECT_LE(a.iterations, b.iterations);
      EXPECT_NEAR(a.final_cost, b.final_cost, 1e-4 * b.final_cost) << "case " << c.free_cams << " rep " << rep;
      int differing = 0;
      for (size_t i = 0; i < s.problem.observations.size(); ++i)
        if (a.inlier[i] != b.inlier[i] && !borderline(s.problem, a, b, i, full)) ++differing;
      EXPECT_EQ(differing, 0);
      for (int k = 0; k < c.free_cams; ++k) {
        EXPECT_LT((a.T_cam_world[k].translation() - b.T_cam_world[k].translation()).norm(), 1e-4);
        EXPECT_LT((a.T_cam_world[k].translation() - s.true_poses[k].translation()).norm(), 0.01);
      }
    }
  EXPECT_LT(iterations_early, iterations_full);
  std::printf("iterations: %d with the early end, %d without\n", iterations_early, iterations_full);
}
