#include "optimize/block_sparse_system.h"

#include <algorithm>
#include <stdexcept>

#include <Eigen/CholmodSupport>

namespace cslam {

struct BlockSparseCameraSystem::Factor {
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> llt;
};

BlockSparseCameraSystem::~BlockSparseCameraSystem() = default;

BlockSparseCameraSystem::BlockSparseCameraSystem(int num_cameras, std::vector<std::vector<int>> rows_below)
    : num_cameras_(num_cameras) {
  if (num_cameras < 1 || int(rows_below.size()) != num_cameras)
    throw std::invalid_argument("BlockSparseCameraSystem: no cameras, or not one row list per camera");
  column_start_.push_back(0);
  for (int col = 0; col < num_cameras; ++col) {
    std::vector<int>& rows = rows_below[size_t(col)];
    std::sort(rows.begin(), rows.end());
    rows.erase(std::unique(rows.begin(), rows.end()), rows.end());
    if (!rows.empty() && (rows.front() <= col || rows.back() >= num_cameras))
      throw std::invalid_argument("BlockSparseCameraSystem: a block outside the lower block triangle");
    block_row_.push_back(col);
    block_row_.insert(block_row_.end(), rows.begin(), rows.end());
    column_start_.push_back(int(block_row_.size()));
  }
  blocks_.assign(block_row_.size(), Matrix6d::Zero());
  if (num_cameras <= kDenseIndexMaxCameras) {
    dense_index_.assign(size_t(num_cameras) * size_t(num_cameras), -1);
    for (int col = 0; col < num_cameras; ++col)
      for (int k = column_start_[size_t(col)]; k < column_start_[size_t(col) + 1]; ++k)
        dense_index_[size_t(block_row_[size_t(k)]) * size_t(num_cameras) + size_t(col)] = k;
  }

  // Column-major storage of the lower triangle: column 6b+c holds rows 6b+c..6b+5 of the
  // diagonal block, then all six rows of each block below it.
  const int n = 6 * num_cameras;
  S_.resize(n, n);
  std::vector<Eigen::Index> outer(size_t(n) + 1, 0);
  for (int b = 0; b < num_cameras; ++b) {
    const int below = column_start_[size_t(b) + 1] - column_start_[size_t(b)] - 1;
    for (int c = 0; c < 6; ++c) outer[size_t(6 * b + c) + 1] = (6 - c) + 6 * below;
  }
  for (int j = 0; j < n; ++j) outer[size_t(j) + 1] += outer[size_t(j)];
  S_.resizeNonZeros(Eigen::Index(outer.back()));
  for (int j = 0; j <= n; ++j) S_.outerIndexPtr()[j] = int(outer[size_t(j)]);
  value_index_.assign(36 * block_row_.size(), -1);
  for (int col = 0; col < num_cameras; ++col)
    for (int k = column_start_[size_t(col)]; k < column_start_[size_t(col) + 1]; ++k) {
      const int row = block_row_[size_t(k)], position = k - column_start_[size_t(col)];  // 0: diagonal
      for (int c = 0; c < 6; ++c) {
        const Eigen::Index first = outer[size_t(6 * col + c)];
        for (int r = position == 0 ? c : 0; r < 6; ++r) {
          const Eigen::Index at = position == 0 ? first + (r - c) : first + (6 - c) + 6 * (position - 1) + r;
          S_.innerIndexPtr()[at] = 6 * row + r;
          S_.valuePtr()[at] = 0.0;
          value_index_[36 * size_t(k) + size_t(6 * c + r)] = int(at);
        }
      }
    }
  factor_ = std::make_unique<Factor>();
  factor_->llt.analyzePattern(S_);
}

int BlockSparseCameraSystem::block_index(int row, int col) const {
  if (col < 0 || col >= num_cameras_ || row < col) return -1;
  if (!dense_index_.empty())
    return row < num_cameras_ ? dense_index_[size_t(row) * size_t(num_cameras_) + size_t(col)] : -1;
  const auto first = block_row_.begin() + column_start_[size_t(col)],
             last = block_row_.begin() + column_start_[size_t(col) + 1];
  const auto it = std::lower_bound(first, last, row);
  return it != last && *it == row ? int(it - block_row_.begin()) : -1;
}

void BlockSparseCameraSystem::set_zero() {
  for (auto& b : blocks_) b.setZero();
}

bool BlockSparseCameraSystem::solve(const Eigen::VectorXd& rhs, Eigen::VectorXd& x) {
  if (rhs.size() != 6 * num_cameras_) throw std::invalid_argument("BlockSparseCameraSystem::solve: rhs size");
  double* values = S_.valuePtr();
  for (size_t k = 0; k < blocks_.size(); ++k) {
    const double* block = blocks_[k].data();
    const int* index = &value_index_[36 * k];
    for (int i = 0; i < 36; ++i)
      if (index[i] >= 0) values[index[i]] = block[i];
  }
  factor_->llt.factorize(S_);
  if (factor_->llt.info() != Eigen::Success) return false;
  x = factor_->llt.solve(rhs);
  return factor_->llt.info() == Eigen::Success;
}

}  // namespace cslam
