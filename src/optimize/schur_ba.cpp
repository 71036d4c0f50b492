#include "optimize/schur_ba.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <type_traits>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "optimize/block_sparse_system.h"
#include "optimize/schur_kernels.h"
#include "optimize/se3_projection.h"

namespace cslam {

namespace {

// One active observation, in the order of its point (points' observations are contiguous).
struct Entry {
  int obs;      // index into BaProblem::observations
  int cam_var;  // index of its camera among the free variable cameras, -1 if the camera is fixed
};

struct Linearization {
  std::vector<Matrix6d> U;         // per free camera: J_c^T W J_c
  std::vector<Vector6d> gc;        // per free camera: J_c^T W r
  std::vector<Eigen::Matrix3d> V;  // per point: J_p^T W J_p
  std::vector<Eigen::Vector3d> gp;
  std::vector<Matrix63d> W;  // per entry (free camera): J_c^T W J_p
  double cost = 0, gradient_max_norm = 0;
  void resize(size_t cams, size_t points, size_t entries) {
    U.resize(cams);
    gc.resize(cams);
    V.resize(points);
    gp.resize(points);
    W.resize(entries);
  }
};

class SchurBaProblem {
 public:
  SchurBaProblem(const BaProblem& prob, const std::vector<char>& active, bool robust, const BaConfig& cfg,
                 std::vector<std::array<double, 6>>& poses, std::vector<Eigen::Vector3d>& points)
      : prob_(prob),
        robust_(robust),
        delta_mono_(std::sqrt(cfg.chi2_mono)),
        delta_stereo_(std::sqrt(cfg.chi2_stereo)),
        poses_(poses),
        points_(points) {
    const int num_cams = int(prob.cameras.size()), num_points = int(prob.points.size());
    std::vector<int> count(num_points, 0), cam_var(num_cams, -2);  // -2: not observed in this stage
    for (size_t i = 0; i < prob.observations.size(); ++i) {
      if (!active[i]) continue;
      const BaObservation& o = prob.observations[i];
      ++count[o.point];
      if (cam_var[o.camera] == -2) {
        cam_var[o.camera] = prob.cameras[o.camera].fixed ? -1 : 0;
        cams_used_.push_back(o.camera);
      }
    }
    for (int c = 0; c < num_cams; ++c)
      if (cam_var[c] == 0) {
        cam_var[c] = int(cam_vars_.size());
        cam_vars_.push_back(c);
      }
    std::vector<int> point_var(num_points, -1);
    point_start_.push_back(0);
    for (int p = 0; p < num_points; ++p)
      if (count[p] > 0) {
        point_var[p] = int(point_vars_.size());
        point_vars_.push_back(p);
        point_start_.push_back(point_start_.back() + count[p]);
      }
    entries_.resize(point_start_.back());
    std::vector<int> fill(point_start_.begin(), point_start_.end() - 1);
    for (size_t i = 0; i < prob.observations.size(); ++i) {
      if (!active[i]) continue;
      const BaObservation& o = prob.observations[i];
      entries_[fill[point_var[o.point]]++] = {int(i), cam_var[o.camera]};
    }
    // Per point, its entries with a free camera (the only ones in the reduced camera system).
    free_start_.push_back(0);
    for (size_t p = 0; p + 1 < point_start_.size(); ++p) {
      for (int e = point_start_[p]; e < point_start_[p + 1]; ++e)
        if (entries_[e].cam_var >= 0) free_entries_.push_back(e);
      free_start_.push_back(int(free_entries_.size()));
    }
    const size_t F = cam_vars_.size(), P = point_vars_.size();
    cur_.resize(F, P, entries_.size());
    next_.resize(F, P, entries_.size());
    lp_.resize(num_cams);
    if (F > size_t(kMaxDenseSchurCameras))
      make_sparse_system();
    else
      S_.resize(6 * F, 6 * F);
    rhs_.resize(6 * F);
    dc_.resize(6 * F);
    Vinv_.resize(P);
    dp_.resize(P);
    int most = 0;
    for (size_t p = 0; p + 1 < free_start_.size(); ++p) most = std::max(most, free_start_[p + 1] - free_start_[p]);
    T_.resize(size_t(most));
    candidate_poses_ = poses_;
    candidate_points_ = points_;
  }

  bool linearize() { return linearize_at(poses_, points_, cur_); }
  double cost() const { return cur_.cost; }
  double gradient_max_norm() const { return cur_.gradient_max_norm; }
  double x_norm() const {
    double n2 = 0;
    for (int c : cam_vars_) n2 += Eigen::Map<const Vector6d>(poses_[c].data()).squaredNorm();
    for (int p : point_vars_) n2 += points_[p].squaredNorm();
    return std::sqrt(n2);
  }

  bool solve(double radius, double& step_norm, double& model_cost_change) {
    if (!(sparse_ ? reduce_sparse(radius) : reduce_dense(radius))) return false;
    back_substitute(step_norm, model_cost_change);
    return std::isfinite(model_cost_change);
  }

  // The reduced camera system at this radius: S = U + damping - sum W V^-1 W^T and
  // rhs = -gc + sum W V^-1 gp. diagonal(v) is camera v's diagonal block of S; add_pairs(begin,
  // end) subtracts T_i W_j^T (T_i = W_i V^-1 in T_) for the free entries [begin, end) of one
  // point, cam_var(j) <= cam_var(i).
  template <class Diagonal, class AddPairs>
  void reduce(double radius, Diagonal&& diagonal, AddPairs&& add_pairs) {
    const Linearization& L = cur_;
    for (int v = 0; v < int(cam_vars_.size()); ++v) {
      Matrix6d Ud = L.U[v];
      for (int d = 0; d < 6; ++d) Ud(d, d) += lm_damping(L.U[v](d, d), radius);
      diagonal(v) = Ud;
      rhs_.segment<6>(6 * v) = -L.gc[v];
    }
    for (size_t p = 0; p < point_vars_.size(); ++p) {
      Eigen::Matrix3d Vd = L.V[p];
      for (int d = 0; d < 3; ++d) Vd(d, d) += lm_damping(L.V[p](d, d), radius);
      Vinv_[p] = Vd.inverse();
      const int begin = free_start_[p], end = free_start_[p + 1];
      for (int i = begin; i < end; ++i) {
        const int e = free_entries_[i];
        Matrix63d& T = T_[size_t(i - begin)];
        T.noalias() = L.W[e] * Vinv_[p];
        rhs_.segment<6>(6 * entries_[e].cam_var).noalias() += T * L.gp[p];
      }
      add_pairs(begin, end);
    }
  }

  // Dense (up to kMaxDenseSchurCameras free cameras): the pair-product kernel on the lower
  // triangle, then a dense Cholesky; solved for the cameras' step dc_.
  bool reduce_dense(double radius) {
    S_.setZero();
    reduce(
        radius, [&](int v) { return S_.block<6, 6>(6 * v, 6 * v); },
        [&](int begin, int end) {
          pair_T_.clear();
          pair_W_.clear();
          pair_cam_.clear();
          for (int i = begin; i < end; ++i) {
            const int e = free_entries_[i];
            pair_T_.push_back(T_[size_t(i - begin)].data());
            pair_W_.push_back(cur_.W[e].data());
            pair_cam_.push_back(entries_[e].cam_var);
          }
          pair_products_(pair_T_.data(), pair_W_.data(), pair_cam_.data(), end - begin, S_.data(), S_.outerStride());
        });
    llt_.compute(S_);
    if (llt_.info() != Eigen::Success) return false;
    dc_ = llt_.solve(rhs_);
    return true;
  }

  // Block-sparse (more free cameras): each pair product lands in the block make_sparse_system
  // found for it, in the same loop order.
  bool reduce_sparse(double radius) {
    sparse_->set_zero();
    const int* pair_block = pair_blocks_.data();
    reduce(
        radius, [&](int v) -> Matrix6d& { return sparse_->block(sparse_->diagonal_index(v)); },
        [&](int begin, int end) {
          for (int i = begin; i < end; ++i) {
            const int a = entries_[free_entries_[i]].cam_var;
            for (int j = begin; j < end; ++j)
              if (entries_[free_entries_[j]].cam_var <= a)
                sparse_->block(*pair_block++).noalias() -= T_[size_t(i - begin)] * cur_.W[free_entries_[j]].transpose();
          }
        });
    return sparse_->solve(rhs_, dc_);
  }

  // The points' step from the cameras' (dp = V^-1 (-gp - W^T dc)), the step's norm and the cost
  // change the linear model predicts.
  void back_substitute(double& step_norm, double& model_cost_change) {
    const Linearization& L = cur_;
    const int F = int(cam_vars_.size());
    double g_dot = 0, h_quad = 0, n2 = dc_.squaredNorm();
    for (int v = 0; v < F; ++v) {
      const Vector6d d = dc_.segment<6>(6 * v);
      g_dot += L.gc[v].dot(d);
      h_quad += d.dot(L.U[v] * d);
    }
    for (size_t p = 0; p < point_vars_.size(); ++p) {
      Eigen::Vector3d b = -L.gp[p];
      for (int e = point_start_[p]; e < point_start_[p + 1]; ++e)
        if (entries_[e].cam_var >= 0) b.noalias() -= L.W[e].transpose() * dc_.segment<6>(6 * entries_[e].cam_var);
      dp_[p].noalias() = Vinv_[p] * b;
      n2 += dp_[p].squaredNorm();
      g_dot += L.gp[p].dot(dp_[p]);
      h_quad += dp_[p].dot(L.V[p] * dp_[p]);
      for (int e = point_start_[p]; e < point_start_[p + 1]; ++e)
        if (entries_[e].cam_var >= 0) h_quad += 2.0 * dc_.segment<6>(6 * entries_[e].cam_var).dot(L.W[e] * dp_[p]);
    }
    step_norm = std::sqrt(n2);
    model_cost_change = -(g_dot + 0.5 * h_quad);
  }

  double try_step() {
    // The candidates equal x outside the variables: copied at construction, and swapped with x
    // on every accepted step.
    for (size_t v = 0; v < cam_vars_.size(); ++v)
      for (int d = 0; d < 6; ++d) candidate_poses_[cam_vars_[v]][d] = poses_[cam_vars_[v]][d] + dc_(6 * v + d);
    for (size_t p = 0; p < point_vars_.size(); ++p)
      candidate_points_[point_vars_[p]] = points_[point_vars_[p]] + dp_[p];
    const double c = cost_at(candidate_poses_, candidate_points_);
    return std::isfinite(c) ? c : std::numeric_limits<double>::infinity();
  }

  bool accept() {
    if (!linearize_at(candidate_poses_, candidate_points_, next_)) return false;
    std::swap(poses_, candidate_poses_);
    std::swap(points_, candidate_points_);
    std::swap(cur_, next_);
    return true;
  }
  void commit() {  // cur_ still describes the previous x: the solve ends here
    std::swap(poses_, candidate_poses_);
    std::swap(points_, candidate_points_);
  }

 private:
  // The block pattern of the reduced system: one block per pair of free cameras that share a
  // point, and the block each pair product of reduce_sparse lands in, in its loop order.
  void make_sparse_system() {
    const int F = int(cam_vars_.size());
    // Each free camera's points, then the cameras below it that share one (marked once per column).
    std::vector<std::vector<int>> points_of(static_cast<size_t>(F)), below(static_cast<size_t>(F));
    for (size_t p = 0; p + 1 < free_start_.size(); ++p)
      for (int i = free_start_[p]; i < free_start_[p + 1]; ++i)
        points_of[size_t(entries_[free_entries_[i]].cam_var)].push_back(int(p));
    std::vector<int> marked(static_cast<size_t>(F), -1);
    size_t pairs = 0;
    for (int b = 0; b < F; ++b)
      for (int p : points_of[size_t(b)])
        for (int i = free_start_[p]; i < free_start_[p + 1]; ++i) {
          const int a = entries_[free_entries_[i]].cam_var;
          if (a >= b) ++pairs;
          if (a > b && marked[size_t(a)] != b) {
            marked[size_t(a)] = b;
            below[size_t(b)].push_back(a);
          }
        }
    sparse_ = std::make_unique<BlockSparseCameraSystem>(F, std::move(below));
    pair_blocks_.reserve(pairs);
    for (size_t p = 0; p + 1 < free_start_.size(); ++p)
      for (int i = free_start_[p]; i < free_start_[p + 1]; ++i) {
        const int a = entries_[free_entries_[i]].cam_var;
        for (int j = free_start_[p]; j < free_start_[p + 1]; ++j)
          if (const int b = entries_[free_entries_[j]].cam_var; b <= a)
            pair_blocks_.push_back(sparse_->block_index(a, b));
      }
  }

  // The cost linearize_at computes, summed in the same order, without derivatives.
  double cost_at(const std::vector<std::array<double, 6>>& poses, const std::vector<Eigen::Vector3d>& points) {
    for (int c : cams_used_) lp_[c].set_transform(poses[c].data());
    double cost = 0;
    for (size_t p = 0; p < point_vars_.size(); ++p) {
      const Eigen::Vector3d& X = points[point_vars_[p]];
      for (int e = point_start_[p]; e < point_start_[p + 1]; ++e) {
        const BaObservation& o = prob_.observations[entries_[e].obs];
        cost += weighted_residual(project_point(prob_.cameras[o.camera].intrinsics, lp_[o.camera], X), o.uv, o.u_right,
                                  o.inv_sigma2, robust_, delta_mono_, delta_stereo_)
                    .cost;
      }
    }
    return 0.5 * cost;
  }

  bool linearize_at(const std::vector<std::array<double, 6>>& poses, const std::vector<Eigen::Vector3d>& points,
                    Linearization& L) {
    for (int c : cams_used_) lp_[c].set(poses[c].data());
    for (auto& m : L.U) m.setZero();
    for (auto& g : L.gc) g.setZero();
    double cost = 0;
    Eigen::Vector3d uvr;
    Matrix36d Jc;
    Eigen::Matrix3d Jp;
    for (size_t p = 0; p < point_vars_.size(); ++p) {
      const Eigen::Vector3d& X = points[point_vars_[p]];
      Eigen::Matrix3d V = Eigen::Matrix3d::Zero();
      Eigen::Vector3d gp = Eigen::Vector3d::Zero();
      for (int e = point_start_[p]; e < point_start_[p + 1]; ++e) {
        const BaObservation& o = prob_.observations[entries_[e].obs];
        const int v = entries_[e].cam_var;
        if (v >= 0)
          project_with_jacobians(prob_.cameras[o.camera].intrinsics, lp_[o.camera], X, uvr, Jc, Jp);
        else
          project_with_point_jacobian(prob_.cameras[o.camera].intrinsics, lp_[o.camera], X, uvr, Jp);
        const WeightedResidual wr =
            weighted_residual(uvr, o.uv, o.u_right, o.inv_sigma2, robust_, delta_mono_, delta_stereo_);
        cost += wr.cost;
        // The rows of the observation's residual only (2 for a monocular one).
        auto accumulate = [&](auto num_rows) {
          constexpr int R = decltype(num_rows)::value;
          const auto Jp_r = Jp.template topRows<R>();
          const auto r_r = wr.r.template head<R>();
          const Eigen::Matrix<double, 3, R> wJpT = wr.weight * Jp_r.transpose();
          V.noalias() += wJpT * Jp_r;
          gp.noalias() += wJpT * r_r;
          if (v >= 0) {
            const auto Jc_r = Jc.template topRows<R>();
            const Eigen::Matrix<double, 6, R> wJcT = wr.weight * Jc_r.transpose();
            L.U[v].noalias() += wJcT * Jc_r;
            L.gc[v].noalias() += wJcT * r_r;
            L.W[e].noalias() = wJcT * Jp_r;
          }
        };
        if (wr.stereo)
          accumulate(std::integral_constant<int, 3>{});
        else
          accumulate(std::integral_constant<int, 2>{});
      }
      L.V[p] = V;
      L.gp[p] = gp;
    }
    L.cost = 0.5 * cost;
    double gmax = 0;
    for (const auto& g : L.gc) gmax = std::max(gmax, g.lpNorm<Eigen::Infinity>());
    for (const auto& g : L.gp) gmax = std::max(gmax, g.lpNorm<Eigen::Infinity>());
    L.gradient_max_norm = gmax;
    return std::isfinite(L.cost) && std::isfinite(gmax);
  }

  const BaProblem& prob_;
  const bool robust_;
  const double delta_mono_, delta_stereo_;
  std::vector<std::array<double, 6>>& poses_;
  std::vector<Eigen::Vector3d>& points_;
  std::vector<int> cams_used_, cam_vars_, point_vars_, point_start_, free_start_, free_entries_;
  std::vector<Entry> entries_;
  std::vector<PoseLinearizationPoint> lp_;
  Linearization cur_, next_;
  Eigen::MatrixXd S_;                                // dense reduced system (up to kMaxDenseSchurCameras)
  std::unique_ptr<BlockSparseCameraSystem> sparse_;  // or the block-sparse one
  std::vector<int> pair_blocks_;                     // sparse_'s block of each pair product
  Eigen::VectorXd rhs_, dc_;
  Eigen::LLT<Eigen::MatrixXd> llt_;
  std::vector<Eigen::Matrix3d> Vinv_;
  std::vector<Eigen::Vector3d> dp_;
  std::vector<Matrix63d> T_;  // W V^-1 of one point's free entries (scratch)
  std::vector<std::array<double, 6>> candidate_poses_;
  std::vector<Eigen::Vector3d> candidate_points_;
  // One point's free entries for the pair-product kernel.
  const schur_kernels::PairProductsFn pair_products_ = schur_kernels::pair_products();
  std::vector<const double*> pair_T_, pair_W_;
  std::vector<int> pair_cam_;
};

}  // namespace

LmOutcome schur_ba_stage(const BaProblem& problem, const std::vector<char>& active, bool robust, const BaConfig& config,
                         int max_iterations, const std::atomic<bool>* abort, std::vector<std::array<double, 6>>& poses,
                         std::vector<Eigen::Vector3d>& points) {
  SchurBaProblem p(problem, active, robust, config, poses, points);
  return levenberg_marquardt(p, max_iterations, abort, config.min_step_decrease, config.keep_progress_on_abort);
}

}  // namespace cslam
