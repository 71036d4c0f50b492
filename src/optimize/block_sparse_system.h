#pragma once
// The reduced camera system of a Schur-complement bundle adjustment with many free cameras,
// stored as the 6x6 blocks of the camera pairs that share a point (the lower block triangle) and
// solved by CHOLMOD's supernodal sparse Cholesky (SuiteSparse, which Debian's Ceres is built
// on). Its pattern is fixed for the life of the object, so the fill-reducing ordering and the
// symbolic analysis are done once, at construction, and each LM iteration only refills the
// blocks and factorises numerically.
//
// A dense reduced system grows as F^2 in memory and F^3 in factorisation time; with a group of
// fused maps (hundreds of keyframes, each seeing a few dozen others) most of its blocks are zero.
#include <memory>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "optimize/se3_projection.h"

namespace cslam {

class BlockSparseCameraSystem {
 public:
  // rows_below[col]: the cameras row > col whose block (row, col) is non-zero, in any order and
  // with repeats; every diagonal block is added.
  BlockSparseCameraSystem(int num_cameras, std::vector<std::vector<int>> rows_below);
  ~BlockSparseCameraSystem();
  BlockSparseCameraSystem(const BlockSparseCameraSystem&) = delete;
  BlockSparseCameraSystem& operator=(const BlockSparseCameraSystem&) = delete;

  int num_blocks() const { return int(blocks_.size()); }
  // The index of block (row, col), row >= col; -1 if it is not in the pattern.
  int block_index(int row, int col) const;
  int diagonal_index(int camera) const { return column_start_[size_t(camera)]; }
  Matrix6d& block(int index) { return blocks_[size_t(index)]; }
  const Matrix6d& block(int index) const { return blocks_[size_t(index)]; }
  void set_zero();

  // Solves S x = rhs with the current blocks (only the lower triangles of the diagonal blocks
  // are read). False if S is not positive definite.
  bool solve(const Eigen::VectorXd& rhs, Eigen::VectorXd& x);

 private:
  // Up to this many cameras, block_index reads a dense table (it runs for every pair of cameras
  // that share a point when a problem is set up: hundreds of thousands of look-ups for a group of
  // fused maps); beyond it, a binary search in the block's column.
  static constexpr int kDenseIndexMaxCameras = 512;

  int num_cameras_;
  std::vector<int> dense_index_;   // row * num_cameras_ + col -> block, -1 outside the pattern; empty beyond the limit
  std::vector<int> column_start_;  // per block column: its first block (the diagonal one); then the rows below
  std::vector<int> block_row_;     // per block: its row camera (ascending within a column)
  std::vector<Matrix6d> blocks_;
  std::vector<int> value_index_;  // per block, 36 entries column-major: index into S_'s values, -1 above the diagonal
  Eigen::SparseMatrix<double> S_;
  struct Factor;  // CHOLMOD's supernodal Cholesky through Eigen (block_sparse_system.cpp)
  std::unique_ptr<Factor> factor_;
};

}  // namespace cslam
