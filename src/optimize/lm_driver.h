#pragma once
// Levenberg-Marquardt step control of Ceres' trust-region minimiser (Ceres 2.1 defaults), shared
// by the fast pose-only and bundle-adjustment solvers so both take the steps the Ceres
// reference takes: initial radius 1e4, radius update on success
// r / max(1/3, 1 - (2 rho - 1)^3), on failure r / f with f doubling; Jacobi-scaled LM diagonal
// clamped to [1e-6, 1e32]; a step is accepted when its relative decrease exceeds 1e-3;
// termination on function tolerance 1e-6 (the candidate is then discarded, as in Ceres),
// gradient tolerance 1e-10, parameter tolerance 1e-8, or the iteration limit. As Ceres, callers
// keep the starting values when the outcome is not usable (abort, numerical failure).
// One rule beyond Ceres' (min_step_decrease > 0): the solve also ends after an accepted step that
// lowered the cost by no more than that fraction. Near the minimum the Gauss-Newton-like steps
// shrink superlinearly, so the next step would change the cost by far less; Ceres' rule finds this
// only by solving that next step and discarding it (a third of the local BA's solves).
#include <algorithm>
#include <atomic>
#include <cmath>

namespace cslam {

struct LmOutcome {
  double initial_cost = 0, final_cost = 0;
  int iterations = 0;      // as Ceres' Solver::Summary::iterations.size() (iteration 0 included)
  bool usable = false;     // CONVERGENCE or NO_CONVERGENCE in Ceres' terms
  bool converged = false;  // CONVERGENCE
  bool aborted = false;    // the abort flag was seen (Ceres' USER_FAILURE)
};

// LM damping of one diagonal entry of J^T J, as Ceres computes it on the Jacobi-scaled Jacobian
// (scale 1 / (1 + sqrt(h))) and maps back to the unscaled system.
inline double lm_damping(double h, double radius) {
  const double s = 1.0 / (1.0 + std::sqrt(h));
  return std::clamp(s * s * h, 1e-6, 1e32) / (s * s * radius);
}

// Problem interface:
//   bool linearize()            at the current x: cost, gradient, normal equations; false if not finite
//   double cost() const, gradient_max_norm() const, x_norm() const
//   bool solve(double radius, double& step_norm, double& model_cost_change)   damped step
//   double try_step()           cost at x + step (no derivatives: most candidates are rejected or
//                               end the solve); +inf if not finite
//   bool accept()               x <- x + step, linearised there; false (nothing changed) if the
//                               derivatives are not finite, and the step counts as rejected
//   void commit()               x <- x + step without derivatives: the accepted step that ends
//                               the solve (early end, last iteration) needs none there
// keep_on_abort: an abort ends the solve usable, at the last accepted iterate (the start if none).
template <class Problem>
LmOutcome levenberg_marquardt(Problem& p, int max_iterations, const std::atomic<bool>* abort = nullptr,
                              double min_step_decrease = 0.0, bool keep_on_abort = false) {
  constexpr double kFunctionTolerance = 1e-6, kGradientTolerance = 1e-10, kParameterTolerance = 1e-8;
  constexpr double kMinRelativeDecrease = 1e-3, kMaxRadius = 1e16, kMinRadius = 1e-32;
  constexpr int kMaxConsecutiveInvalidSteps = 5;
  LmOutcome out;
  out.iterations = 1;
  if (!p.linearize()) return out;
  out.initial_cost = out.final_cost = p.cost();
  out.usable = true;
  if (p.gradient_max_norm() <= kGradientTolerance) {
    out.converged = true;
    return out;
  }
  auto aborted = [&] { return abort && abort->load(); };
  if (aborted()) {
    out.usable = keep_on_abort;
    out.aborted = true;
    return out;
  }
  double radius = 1e4, decrease_factor = 2.0;
  int invalid_steps = 0;
  for (int iteration = 1; iteration <= max_iterations; ++iteration) {
    double step_norm = 0, model_cost_change = 0;
    const bool valid =
        p.solve(radius, step_norm, model_cost_change) && model_cost_change > 0 && std::isfinite(step_norm);
    if (!valid) {
      if (++invalid_steps >= kMaxConsecutiveInvalidSteps) {
        out.usable = false;
        return out;
      }
      radius /= decrease_factor;
      decrease_factor *= 2.0;
    } else {
      invalid_steps = 0;
      if (step_norm <= kParameterTolerance * (p.x_norm() + kParameterTolerance)) {
        out.converged = true;
        return out;
      }
      const double cost = p.cost(), candidate_cost = p.try_step();
      if (std::abs(cost - candidate_cost) <= kFunctionTolerance * cost) {
        out.converged = true;
        return out;
      }
      const double relative_decrease = (cost - candidate_cost) / model_cost_change;
      const bool acceptable = std::isfinite(candidate_cost) && relative_decrease > kMinRelativeDecrease;
      // An accepted step that ends the solve (too small a decrease, or the last iteration) is
      // taken without linearising there: nothing reads those derivatives. try_step's cost is
      // the one linearising would compute.
      const bool small = cost - candidate_cost <= min_step_decrease * cost;
      if (acceptable && (small || iteration == max_iterations)) {
        p.commit();
        out.final_cost = candidate_cost;
        radius = std::min(kMaxRadius, radius / std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * relative_decrease - 1.0, 3)));
        if (small) {
          ++out.iterations;  // this step counts, as every completed iteration does
          out.converged = true;
          return out;
        }
      } else if (acceptable && p.accept()) {
        out.final_cost = p.cost();
        radius = std::min(kMaxRadius, radius / std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * relative_decrease - 1.0, 3)));
        decrease_factor = 2.0;
        if (p.gradient_max_norm() <= kGradientTolerance) {
          out.converged = true;
          return out;
        }
      } else {
        radius /= decrease_factor;
        decrease_factor *= 2.0;
      }
    }
    ++out.iterations;
    if (aborted()) {
      out.usable = keep_on_abort;
      out.aborted = true;
      return out;
    }
    if (radius < kMinRadius) {
      out.converged = true;
      return out;
    }
  }
  return out;
}

}  // namespace cslam
