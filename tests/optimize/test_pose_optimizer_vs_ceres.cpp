// The fixed-size LM pose optimiser against the Ceres reference on randomized tracking-like
// problems (mono and stereo observations, outliers): same inlier sets, same poses up to the
// solvers' convergence tolerance, and bit-identical output on repeated calls.
#include <gtest/gtest.h>

#include "support/problems/optimize_problems.h"
#include "optimize/ceres_reference.h"
#include "optimize/pose_optimizer.h"

using namespace cslam;

namespace {

// Observations whose chi2 lies this close to the threshold at either solution may legitimately
// flip between two solvers that agree to rounding in the pose; they are counted, not compared.
bool borderline(const SE3& a, const SE3& b, const PoseObservation& o, const StereoIntrinsics& k,
                const PoseOptimizationConfig& cfg) {
  const double thr = o.u_right >= 0 ? cfg.chi2_stereo : cfg.chi2_mono;
  return std::abs(observation_chi2(a, o, k) - thr) < 1e-4 * thr ||
         std::abs(observation_chi2(b, o, k) - thr) < 1e-4 * thr;
}

struct Case {
  int n;
  double outliers, stereo;
};

}  // namespace

TEST(PoseOptimizerVsCeres, SameInliersAndPosesOnRandomProblems) {
  const auto k = problems::tum_like_intrinsics();
  PoseOptimizationConfig cfg;
  cfg.min_step_decrease = 0;  // step for step with Ceres: its termination rules alone
  const Case cases[] = {{30, 0.0, 1.0},  {80, 0.1, 0.8},   {150, 0.2, 0.5},
                        {300, 0.3, 0.9}, {500, 0.15, 0.0}, {250, 0.05, 1.0}};
  std::mt19937 rng(2024);
  int problems = 0, borderline_count = 0;
  double worst_rot = 0, worst_trans = 0;
  for (const Case& c : cases) {
    for (int rep = 0; rep < 10; ++rep, ++problems) {
      const problems::PoseProblem p = problems::random_pose_problem(rng, c.n, c.outliers, c.stereo);
      const auto fast = optimize_pose(p.start, p.obs, k, cfg);
      const auto ref = optimize_pose_ceres(p.start, p.obs, k, cfg);
      const double rot = fast.T_cam_world.rotation().angularDistance(ref.T_cam_world.rotation());
      const double trans = (fast.T_cam_world.translation() - ref.T_cam_world.translation()).norm();
      worst_rot = std::max(worst_rot, rot);
      worst_trans = std::max(worst_trans, trans);
      EXPECT_LT(rot, 1e-9) << "n " << c.n << " rep " << rep;
      EXPECT_LT(trans, 1e-9) << "n " << c.n << " rep " << rep;
      ASSERT_EQ(fast.inlier.size(), ref.inlier.size());
      int differing = 0;
      for (size_t i = 0; i < p.obs.size(); ++i) {
        if (fast.inlier[i] == ref.inlier[i]) continue;
        if (borderline(fast.T_cam_world, ref.T_cam_world, p.obs[i], k, cfg)) {
          ++borderline_count;
          continue;
        }
        ++differing;
      }
      EXPECT_EQ(differing, 0) << "n " << c.n << " rep " << rep;
      EXPECT_NEAR(fast.num_inliers, ref.num_inliers, 1) << "n " << c.n << " rep " << rep;
      EXPECT_NEAR(fast.final_cost, ref.final_cost, 1e-6 * std::max(1.0, ref.final_cost))
          << "n " << c.n << " rep " << rep;
      // Both recover the true pose (the problems are well posed).
      EXPECT_LT((fast.T_cam_world.translation() - p.truth.translation()).norm(), 0.05);
    }
  }
  EXPECT_LE(borderline_count, 2) << "out of " << problems << " problems";
  std::printf("worst rotation difference %.3g rad, translation %.3g m, borderline flips %d\n", worst_rot, worst_trans,
              borderline_count);
}

TEST(PoseOptimizerVsCeres, RepeatedCallsAreBitIdentical) {
  const auto k = problems::tum_like_intrinsics();
  std::mt19937 rng(99);
  const problems::PoseProblem p = problems::random_pose_problem(rng, 200, 0.2, 0.7);
  const auto a = optimize_pose(p.start, p.obs, k);
  const auto b = optimize_pose(p.start, p.obs, k);
  EXPECT_EQ(a.T_cam_world.rotation().coeffs(), b.T_cam_world.rotation().coeffs());
  EXPECT_EQ(a.T_cam_world.translation(), b.T_cam_world.translation());
  EXPECT_EQ(a.inlier, b.inlier);
  EXPECT_EQ(a.final_cost, b.final_cost);
}

TEST(PoseOptimizerVsCeres, RejectsEveryGrossOutlier) {
  const auto k = problems::tum_like_intrinsics();
  std::mt19937 rng(5);
  const problems::PoseProblem p = problems::random_pose_problem(rng, 300, 0.25, 0.8);
  const auto r = optimize_pose(p.start, p.obs, k);
  int kept_outliers = 0, lost_inliers = 0, outliers = 0;
  for (size_t i = 0; i < p.obs.size(); ++i) {
    outliers += p.is_outlier[i];
    // A random "outlier" can land on its true projection by chance: only gross ones count.
    const bool gross = p.is_outlier[i] && observation_chi2(p.truth, p.obs[i], k) > 100;
    if (gross && r.inlier[i]) ++kept_outliers;
    if (!p.is_outlier[i] && !r.inlier[i]) ++lost_inliers;
  }
  EXPECT_GT(outliers, 40);
  EXPECT_EQ(kept_outliers, 0);
  EXPECT_LT(lost_inliers, 15);
}

// The default early end (a round stops after a step that lowered its cost by <= 1e-4 of it): the
// same inliers and, up to a sliver of the cost, the same pose.
TEST(PoseOptimizerVsCeres, EarlyEndAfterATinyStepStaysAtTheFullSolution) {
  const auto k = problems::tum_like_intrinsics();
  PoseOptimizationConfig full;
  full.min_step_decrease = 0;
  const PoseOptimizationConfig early;
  ASSERT_GT(early.min_step_decrease, 0.0);
  std::mt19937 rng(515);
  for (int rep = 0; rep < 40; ++rep) {
    const problems::PoseProblem p =
        problems::random_pose_problem(rng, 50 + 10 * rep, 0.1 + 0.005 * rep, rep % 2 ? 0.8 : 0.2);
    const auto a = optimize_pose(p.start, p.obs, k, early), b = optimize_pose(p.start, p.obs, k, full);
    EXPECT_NEAR(a.final_cost, b.final_cost, 1e-4 * std::max(1.0, b.final_cost)) << "rep " << rep;
    EXPECT_LT((a.T_cam_world.translation() - b.T_cam_world.translation()).norm(), 1e-4) << "rep " << rep;
    EXPECT_LT(a.T_cam_world.rotation().angularDistance(b.T_cam_world.rotation()), 1e-5) << "rep " << rep;
    int differing = 0;
    for (size_t i = 0; i < p.obs.size(); ++i)
      if (a.inlier[i] != b.inlier[i] && !borderline(a.T_cam_world, b.T_cam_world, p.obs[i], k, full)) ++differing;
    EXPECT_EQ(differing, 0) << "rep " << rep;
  }
}
