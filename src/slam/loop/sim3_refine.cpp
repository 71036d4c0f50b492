// Sim3 refinement by Levenberg-Marquardt with analytic Jacobians (sim3_projection.h). It minimises
// the cost of the Ceres reference (refine_sim3_ceres: 0.5 sum rho(|r|^2) over both images'
// whitened residuals, Cauchy then Huber) in the same parameters with the same step control
// (optimize/lm_driver.h, optimize/small_lm_problem.h), so it ends where Ceres ends, without
// building a Ceres problem (with autodiff cost functions and a dense QR) per stage.
#include "slam/loop/sim3_refine.h"

#include <array>
#include <cmath>

#include "core/error.h"
#include "optimize/lm_driver.h"
#include "optimize/small_lm_problem.h"
#include "slam/loop/sim3_costs.h"
#include "slam/loop/sim3_projection.h"

namespace cslam {

namespace {

constexpr int kIterationsPerStage = 10;

enum class Kernel { kCauchy, kHuber };

// rho and rho' of Ceres' CauchyLoss(delta) / HuberLoss(delta) at the squared norm s. Both have
// rho'' <= 0, for which Ceres' residual correction is plain IRLS with weight rho'.
struct KernelValue {
  double rho, weight;
};
KernelValue apply_kernel(Kernel kernel, double s, double delta2) {
  if (kernel == Kernel::kCauchy) {
    const double sum = 1.0 + s / delta2;
    return {delta2 * std::log(sum), 1.0 / sum};
  }
  const HuberValue h = huber(s, std::sqrt(delta2), delta2);
  return {h.rho, h.weight};
}

class Sim3Problem : public SmallLmProblem<7, Sim3Problem> {
 public:
  // fix_scale holds the log-scale (the last parameter), as Ceres holds a constant block.
  Sim3Problem(const std::vector<Sim3Correspondence>& matches, const std::vector<char>& use, const StereoIntrinsics& k1,
              const StereoIntrinsics& k2, double chi2, Kernel kernel, bool fix_scale, std::array<double, 7>& x)
      : SmallLmProblem(x, fix_scale ? 6 : 7),
        matches_(matches),
        use_(use),
        k1_(k1),
        k2_(k2),
        delta2_(chi2),
        kernel_(kernel) {}

  // The cost linearize_at computes, summed in the same order, without derivatives.
  double cost_at(const double* x) const {
    Sim3LinearizationPoint S;
    S.set_transform(x);
    double cost = 0;
    for (std::size_t i = 0; i < matches_.size(); ++i) {
      if (!use_[i]) continue;
      const Sim3Correspondence& m = matches_[i];
      cost +=
          apply_kernel(kernel_, sim3_residual_1(S, m, k1_, 1.0 / std::sqrt(m.sigma2_1), nullptr).squaredNorm(), delta2_)
              .rho;
      cost +=
          apply_kernel(kernel_, sim3_residual_2(S, m, k2_, 1.0 / std::sqrt(m.sigma2_2), nullptr).squaredNorm(), delta2_)
              .rho;
    }
    return 0.5 * cost;
  }

  bool linearize_at(const double* x, SmallLinearization<7>& lin) const {
    Sim3LinearizationPoint S;
    S.set(x);
    lin.H.setZero();
    lin.g.setZero();
    double cost = 0;
    Matrix27d J;
    auto add = [&](const Eigen::Vector2d& r) {
      const KernelValue kv = apply_kernel(kernel_, r.squaredNorm(), delta2_);
      cost += kv.rho;
      lin.H.noalias() += (kv.weight * J.transpose()) * J;
      lin.g.noalias() += (kv.weight * J.transpose()) * r;
    };
    for (std::size_t i = 0; i < matches_.size(); ++i) {
      if (!use_[i]) continue;
      const Sim3Correspondence& m = matches_[i];
      add(sim3_residual_1(S, m, k1_, 1.0 / std::sqrt(m.sigma2_1), &J));
      add(sim3_residual_2(S, m, k2_, 1.0 / std::sqrt(m.sigma2_2), &J));
    }
    lin.cost = 0.5 * cost;
    return std::isfinite(lin.cost) && lin.H.allFinite() && lin.g.allFinite();
  }

 private:
  const std::vector<Sim3Correspondence>& matches_;
  const std::vector<char>& use_;
  const StereoIntrinsics &k1_, &k2_;
  const double delta2_;
  const Kernel kernel_;
};

std::array<double, 7> to_x(const Sim3& S) {
  const Sim3Param p = to_sim3_param(S);
  return {p.pose[0], p.pose[1], p.pose[2], p.pose[3], p.pose[4], p.pose[5], p.log_scale};
}

Sim3 from_x(const std::array<double, 7>& x) { return from_sim3_param(x.data(), x[6]); }

// One stage on the matches flagged in `use`; as Ceres, an unusable solve leaves x unchanged.
bool run_stage(const std::vector<Sim3Correspondence>& matches, const std::vector<char>& use, const StereoIntrinsics& k1,
               const StereoIntrinsics& k2, double chi2, Kernel kernel, bool fix_scale, std::array<double, 7>& x) {
  const std::array<double, 7> before = x;
  Sim3Problem problem(matches, use, k1, k2, chi2, kernel, fix_scale, x);
  const LmOutcome lm = levenberg_marquardt(problem, kIterationsPerStage);
  if (!lm.usable) x = before;
  return lm.converged;
}

}  // namespace

int classify_sim3_matches(const Sim3& S_12, const std::vector<Sim3Correspondence>& matches, const StereoIntrinsics& k1,
                          const StereoIntrinsics& k2, double chi2, std::vector<char>& inlier) {
  int n = 0;
  inlier.assign(matches.size(), 0);
  for (std::size_t i = 0; i < matches.size(); ++i) {
    const auto e = sim3_match_chi2(S_12, matches[i], k1, k2);
    inlier[i] = e.e1 <= chi2 && e.e2 <= chi2;
    n += inlier[i];
  }
  return n;
}

Sim3RefineResult refine_sim3(const Sim3& S_12_initial, const std::vector<Sim3Correspondence>& matches,
                             const StereoIntrinsics& k1, const StereoIntrinsics& k2, bool fix_scale, double chi2) {
  if (!(chi2 > 0)) throw ConfigError("refine_sim3: chi2 must be > 0");
  Sim3RefineResult res;
  res.S_12 = S_12_initial;
  res.inlier.assign(matches.size(), 0);
  if (matches.size() < 3) return res;

  const std::array<double, 7> initial = to_x(S_12_initial);
  std::array<double, 7> x = initial;
  res.converged = run_stage(matches, std::vector<char>(matches.size(), 1), k1, k2, chi2, Kernel::kCauchy, fix_scale, x);
  std::vector<char> inlier;
  if (classify_sim3_matches(from_x(x), matches, k1, k2, chi2, inlier) >= 3)
    res.converged = run_stage(matches, inlier, k1, k2, chi2, Kernel::kHuber, fix_scale, x);
  res.S_12 = from_x(x);
  res.num_inliers = classify_sim3_matches(res.S_12, matches, k1, k2, chi2, res.inlier);
  // Huber cost of the final inliers at the initial and the refined estimate.
  if (res.num_inliers > 0) {
    std::array<double, 7> scratch = initial;
    const Sim3Problem final_set(matches, res.inlier, k1, k2, chi2, Kernel::kHuber, fix_scale, scratch);
    res.initial_cost = final_set.cost_at(initial.data());
    res.final_cost = final_set.cost_at(x.data());
  }
  return res;
}

}  // namespace cslam
