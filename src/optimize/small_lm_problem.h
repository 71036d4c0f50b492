#pragma once
// The problem side of lm_driver.h for small problems: N parameters updated additively (x <- x +
// step), dense N x N normal equations solved by LDLT, the first `free` parameters varied and the
// rest held (as Ceres holds a constant parameter block: left out of the step, the gradient norm
// and the parameter norm). Used by the pose-only optimisation (N = 6) and the Sim3 refinement
// (N = 7, the scale held with a fixed scale).
//
// Derived supplies, at parameters x:
//   bool linearize_at(const double* x, SmallLinearization<N>& lin) const   cost (0.5 sum rho),
//        gradient and normal equations; false if not finite
//   double cost_at(const double* x) const   the same cost, summed in the same order, no derivatives
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "optimize/lm_driver.h"

namespace cslam {

template <int N>
struct SmallLinearization {
  Eigen::Matrix<double, N, N> H = Eigen::Matrix<double, N, N>::Zero();  // J^T W J
  Eigen::Matrix<double, N, 1> g = Eigen::Matrix<double, N, 1>::Zero();  // J^T W r
  double cost = 0;
};

template <int N, class Derived>
class SmallLmProblem {
 public:
  using Vector = Eigen::Matrix<double, N, 1>;
  using Matrix = Eigen::Matrix<double, N, N>;

  // Throws std::invalid_argument unless 1 <= free <= N.
  SmallLmProblem(std::array<double, N>& x, int free) : x_(x), free_(free) {
    if (free < 1 || free > N) throw std::invalid_argument("SmallLmProblem: free parameters outside [1, N]");
  }

  bool linearize() { return derived().linearize_at(x_.data(), cur_); }
  double cost() const { return cur_.cost; }
  double gradient_max_norm() const { return cur_.g.head(free_).template lpNorm<Eigen::Infinity>(); }
  double x_norm() const { return Eigen::Map<const Vector>(x_.data()).head(free_).norm(); }

  bool solve(double radius, double& step_norm, double& model_cost_change) {
    if (free_ == N) {
      Matrix A = cur_.H;
      for (int d = 0; d < N; ++d) A(d, d) += lm_damping(cur_.H(d, d), radius);
      step_ = -A.ldlt().solve(cur_.g);
    } else {
      using Free = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, N, N>;
      Free A = cur_.H.topLeftCorner(free_, free_);
      for (int d = 0; d < free_; ++d) A(d, d) += lm_damping(cur_.H(d, d), radius);
      step_.setZero();
      step_.head(free_) = -A.ldlt().solve(cur_.g.head(free_));
    }
    step_norm = step_.norm();
    model_cost_change = -(cur_.g.dot(step_) + 0.5 * step_.dot(cur_.H * step_));
    return step_.allFinite();
  }
  double try_step() {
    for (int d = 0; d < N; ++d) candidate_x_[d] = x_[d] + step_(d);
    const double c = derived().cost_at(candidate_x_.data());
    return std::isfinite(c) ? c : std::numeric_limits<double>::infinity();
  }
  bool accept() {
    if (!derived().linearize_at(candidate_x_.data(), next_)) return false;
    x_ = candidate_x_;
    std::swap(cur_, next_);
    return true;
  }
  void commit() { x_ = candidate_x_; }  // cur_ still describes the previous x: the solve ends here

 private:
  const Derived& derived() const { return static_cast<const Derived&>(*this); }

  std::array<double, N>& x_;
  const int free_;
  std::array<double, N> candidate_x_{};
  Vector step_ = Vector::Zero();
  SmallLinearization<N> cur_, next_;
};

}  // namespace cslam
