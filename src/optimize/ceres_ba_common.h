#pragma once
// Glue shared by the Ceres bundle-adjustment paths (the tuned one and the reference): the abort
// flag as an iteration callback, and the solver summary folded into a BaResult.
#include <atomic>

#include <ceres/ceres.h>

#include "optimize/bundle_adjustment.h"

namespace cslam::ceres_ba {

class AbortCallback : public ceres::IterationCallback {
 public:
  // keep_progress: the solver ends at its current (last accepted) iterate, as USER_SUCCESS.
  AbortCallback(const std::atomic<bool>* flag, bool keep_progress) : flag_(flag), keep_progress_(keep_progress) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    if (!flag_ || !flag_->load()) return ceres::SOLVER_CONTINUE;
    return keep_progress_ ? ceres::SOLVER_TERMINATE_SUCCESSFULLY : ceres::SOLVER_ABORT;
  }

 private:
  const std::atomic<bool>* flag_;
  bool keep_progress_;
};

// Adds one solver stage to `res`: the first stage's initial cost, the last one's final cost.
inline void accumulate(const ceres::Solver::Summary& summary, BaResult& res) {
  if (res.iterations == 0) res.initial_cost = summary.initial_cost;
  res.final_cost = summary.final_cost;
  res.iterations += int(summary.iterations.size());
  res.converged = summary.termination_type == ceres::CONVERGENCE || summary.termination_type == ceres::NO_CONVERGENCE;
  if (summary.termination_type == ceres::USER_FAILURE) res.aborted = true;
  if (summary.termination_type == ceres::USER_SUCCESS) res.aborted = res.partial = res.converged = true;
}

}  // namespace cslam::ceres_ba
