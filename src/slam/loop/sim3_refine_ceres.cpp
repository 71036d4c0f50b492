// The Ceres reference of refine_sim3 (tests and cslam-bench-loop compare the two).
#include "slam/loop/sim3_refine.h"

#include <cmath>
#include <memory>

#include <ceres/ceres.h>

#include "core/error.h"
#include "slam/loop/sim3_costs.h"

namespace cslam {

namespace {

constexpr int kIterationsPerStage = 10;

// Adds both image residuals of every selected match to `problem`.
enum class Kernel { kCauchy, kHuber };

void add_matches(ceres::Problem& problem, Sim3Param& param, const std::vector<Sim3Correspondence>& matches,
                 const std::vector<char>& use, const StereoIntrinsics& k1, const StereoIntrinsics& k2, double chi2,
                 Kernel kernel) {
  const double delta = std::sqrt(chi2);
  auto loss = [&]() -> ceres::LossFunction* {
    if (kernel == Kernel::kCauchy) return new ceres::CauchyLoss(delta);
    return new ceres::HuberLoss(delta);
  };
  for (size_t i = 0; i < matches.size(); ++i) {
    if (!use[i]) continue;
    const auto& m = matches[i];
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Sim3ReprojectionCost1, 2, 6, 1>(
                                 new Sim3ReprojectionCost1(k1, m.p2, m.uv1, 1.0 / std::sqrt(m.sigma2_1), m.T_view_1)),
                             loss(), param.pose.data(), &param.log_scale);
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Sim3ReprojectionCost2, 2, 6, 1>(
                                 new Sim3ReprojectionCost2(k2, m.p1, m.uv2, 1.0 / std::sqrt(m.sigma2_2))),
                             loss(), param.pose.data(), &param.log_scale);
  }
}

ceres::Solver::Summary solve(ceres::Problem& problem, Sim3Param& param, bool fix_scale) {
  if (fix_scale) problem.SetParameterBlockConstant(&param.log_scale);
  ceres::Solver::Options opts;
  opts.linear_solver_type = ceres::DENSE_QR;
  opts.max_num_iterations = kIterationsPerStage;
  opts.num_threads = 1;
  opts.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(opts, &problem, &summary);
  return summary;
}

}  // namespace

Sim3RefineResult refine_sim3_ceres(const Sim3& S_12_initial, const std::vector<Sim3Correspondence>& matches,
                                   const StereoIntrinsics& k1, const StereoIntrinsics& k2, bool fix_scale,
                                   double chi2) {
  if (!(chi2 > 0)) throw ConfigError("refine_sim3_ceres: chi2 must be > 0");
  Sim3RefineResult res;
  res.S_12 = S_12_initial;
  res.inlier.assign(matches.size(), 0);
  if (matches.size() < 3) return res;

  const Sim3Param initial = to_sim3_param(S_12_initial);
  Sim3Param param = initial;
  ceres::Problem::Options popts;
  popts.loss_function_ownership = ceres::TAKE_OWNERSHIP;
  {
    ceres::Problem all(popts);
    add_matches(all, param, matches, std::vector<char>(matches.size(), 1), k1, k2, chi2, Kernel::kCauchy);
    res.converged = solve(all, param, fix_scale).termination_type == ceres::CONVERGENCE;
  }
  std::vector<char> inlier;
  const int n1 =
      classify_sim3_matches(from_sim3_param(param.pose.data(), param.log_scale), matches, k1, k2, chi2, inlier);
  if (n1 >= 3) {
    ceres::Problem kept(popts);
    add_matches(kept, param, matches, inlier, k1, k2, chi2, Kernel::kHuber);
    res.converged = solve(kept, param, fix_scale).termination_type == ceres::CONVERGENCE;
  }
  res.S_12 = from_sim3_param(param.pose.data(), param.log_scale);
  res.num_inliers = classify_sim3_matches(res.S_12, matches, k1, k2, chi2, res.inlier);
  // Huber cost of the final inliers at the initial and the refined estimate.
  if (res.num_inliers > 0) {
    Sim3Param eval = initial;
    ceres::Problem final_set(popts);
    add_matches(final_set, eval, matches, res.inlier, k1, k2, chi2, Kernel::kHuber);
    final_set.Evaluate(ceres::Problem::EvaluateOptions(), &res.initial_cost, nullptr, nullptr, nullptr);
    eval = param;
    final_set.Evaluate(ceres::Problem::EvaluateOptions(), &res.final_cost, nullptr, nullptr, nullptr);
  }
  return res;
}

}  // namespace cslam
