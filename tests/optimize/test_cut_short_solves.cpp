// Solves cut short with their progress kept (BaConfig::keep_progress_on_abort): the LM driver ends
// usable at its last accepted iterate, the Ceres glue ends as USER_SUCCESS with the iterate
// written, and an abort before the first step leaves the start, usable.
#include <atomic>
#include <cmath>

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include "optimize/bundle_adjustment.h"
#include "optimize/ceres_ba_common.h"
#include "optimize/lm_driver.h"
#include "support/problems/optimize_problems.h"

using namespace cslam;

namespace {

// One residual r(x) = exp(x) - 2 (minimum at ln 2), LM on the scalar normal equation. The abort
// flag is raised by the first accepted step, so the solve is cut short right after it.
struct ExpProblem {
  double x = 3.0, candidate = 0, step = 0, r = 0, J = 0;
  std::atomic<bool>* raise_on_accept = nullptr;
  bool linearize() {
    r = std::exp(x) - 2.0;
    J = std::exp(x);
    return std::isfinite(r);
  }
  double cost() const { return 0.5 * r * r; }
  double gradient_max_norm() const { return std::abs(J * r); }
  double x_norm() const { return std::abs(x); }
  bool solve(double radius, double& step_norm, double& model_cost_change) {
    const double H = J * J, g = J * r;
    step = -g / (H + lm_damping(H, radius));
    step_norm = std::abs(step);
    model_cost_change = -(g * step + 0.5 * H * step * step);
    return true;
  }
  double try_step() {
    candidate = x + step;
    const double rc = std::exp(candidate) - 2.0;
    return 0.5 * rc * rc;
  }
  bool accept() {
    x = candidate;
    if (raise_on_accept) raise_on_accept->store(true);
    return linearize();
  }
  void commit() { x = candidate; }
};

struct ExpCost : ceres::SizedCostFunction<1, 1> {
  bool Evaluate(double const* const* p, double* residual, double** jacobian) const override {
    residual[0] = std::exp(p[0][0]) - 2.0;
    if (jacobian && jacobian[0]) jacobian[0][0] = std::exp(p[0][0]);
    return true;
  }
};

// Raises the flag at the end of the first iteration, before the abort callback reads it.
struct RaiseAfterFirst : ceres::IterationCallback {
  std::atomic<bool>* flag;
  explicit RaiseAfterFirst(std::atomic<bool>* f) : flag(f) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (s.iteration >= 1 && s.step_is_successful) flag->store(true);
    return ceres::SOLVER_CONTINUE;
  }
};

}  // namespace

TEST(CutShortSolves, LmDriverKeepsTheLastAcceptedIterateOnlyWhenAsked) {
  for (const bool keep : {false, true}) {
    std::atomic<bool> abort{false};
    ExpProblem p;
    p.raise_on_accept = &abort;
    const LmOutcome out = levenberg_marquardt(p, 50, &abort, 0.0, keep);
    EXPECT_TRUE(out.aborted);
    EXPECT_EQ(out.usable, keep);
    EXPECT_LT(p.x, 3.0) << "one step was accepted before the abort";
    EXPECT_GT(p.x, std::log(2.0) + 0.1) << "cut short well before the minimum";
    EXPECT_LT(out.final_cost, out.initial_cost);
  }
  // Not aborted: the solve runs to the minimum.
  ExpProblem p;
  const LmOutcome out = levenberg_marquardt(p, 50, nullptr, 0.0, true);
  EXPECT_FALSE(out.aborted);
  EXPECT_NEAR(p.x, std::log(2.0), 1e-6);
}

TEST(CutShortSolves, CeresGlueEndsAsUserSuccessWithTheIterateWritten) {
  for (const bool keep : {false, true}) {
    double x = 3.0;
    ceres::Problem problem;
    problem.AddResidualBlock(new ExpCost, nullptr, &x);
    std::atomic<bool> abort{false};
    RaiseAfterFirst raise(&abort);
    ceres_ba::AbortCallback cut(&abort, keep);
    ceres::Solver::Options opts;
    opts.max_num_iterations = 50;
    opts.logging_type = ceres::SILENT;
    opts.callbacks = {&raise, &cut};
    ceres::Solver::Summary summary;
    ceres::Solve(opts, &problem, &summary);
    BaResult res;
    ceres_ba::accumulate(summary, res);
    EXPECT_TRUE(res.aborted);
    EXPECT_EQ(res.partial, keep);
    if (keep) {
      EXPECT_EQ(summary.termination_type, ceres::USER_SUCCESS);
      EXPECT_LT(x, 3.0);
      EXPECT_GT(x, std::log(2.0) + 1e-3) << "cut short before the minimum";
    } else {
      EXPECT_EQ(summary.termination_type, ceres::USER_FAILURE);
      EXPECT_EQ(x, 3.0) << "an abort without keep writes nothing";
    }
  }
}

TEST(CutShortSolves, AbortBeforeTheFirstStepKeepsTheStartUsable) {
  std::mt19937 rng(9);
  const problems::BaSynthetic s = problems::random_ba_problem(rng, 5, 2, 200, 0.05, 0.7);
  std::atomic<bool> abort{true};
  BaConfig cfg;
  cfg.keep_progress_on_abort = true;
  const BaResult r = bundle_adjust(s.problem, cfg, &abort);
  EXPECT_TRUE(r.aborted);
  EXPECT_TRUE(r.partial);
  EXPECT_EQ(r.final_cost, r.initial_cost);
  for (size_t k = 0; k < s.problem.points.size(); ++k) EXPECT_LT((r.points[k] - s.problem.points[k]).norm(), 1e-15);
}
