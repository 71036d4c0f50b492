// The block-sparse reduced camera system against a dense Cholesky of the same matrix: random
// symmetric positive definite systems with a random block pattern, the pattern's lookups, bad
// pairs, and a matrix that is not positive definite.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

#include <Eigen/Cholesky>

#include "optimize/block_sparse_system.h"

using namespace cslam;

namespace {

// A random pattern as (row, col) pairs, row >= col: each camera linked to the next (a
// trajectory) and to a few random others, with repeats and diagonal pairs.
std::vector<std::pair<int, int>> random_pattern(std::mt19937& rng, int n) {
  std::vector<std::pair<int, int>> pairs;
  std::uniform_int_distribution<int> any(0, n - 1);
  for (int c = 1; c < n; ++c) pairs.emplace_back(c, c - 1);
  for (int k = 0; k < 2 * n; ++k) {
    const int a = any(rng), b = any(rng);
    pairs.emplace_back(std::max(a, b), std::min(a, b));
  }
  return pairs;
}

std::vector<std::vector<int>> rows_below(int n, const std::vector<std::pair<int, int>>& pairs) {
  std::vector<std::vector<int>> below(static_cast<size_t>(n));
  for (const auto& [a, b] : pairs)
    if (a > b) below[size_t(b)].push_back(a);
  return below;
}

}  // namespace

TEST(BlockSparseCameraSystem, SolvesAsADenseCholesky) {
  std::mt19937 rng(5);
  std::normal_distribution<double> N(0, 1);
  for (int n : {1, 2, 7, 40, 130}) {
    const auto pairs = random_pattern(rng, n);
    BlockSparseCameraSystem S(n, rows_below(n, pairs));
    // The dense matrix: random off-diagonal blocks on the pattern, a dominant diagonal.
    Eigen::MatrixXd D = Eigen::MatrixXd::Zero(6 * n, 6 * n);
    for (const auto& [a, b] : pairs) {
      if (a == b) continue;
      Matrix6d B;
      for (int i = 0; i < 36; ++i) B.data()[i] = N(rng);
      D.block<6, 6>(6 * a, 6 * b) += B;
      D.block<6, 6>(6 * b, 6 * a) += B.transpose();
    }
    for (int i = 0; i < 6 * n; ++i) D(i, i) += 12.0 * 6 * (n + 1);
    S.set_zero();
    for (int a = 0; a < n; ++a)
      for (int b = 0; b <= a; ++b) {
        const int k = S.block_index(a, b);
        if (k < 0) {
          EXPECT_EQ((D.block<6, 6>(6 * a, 6 * b).norm()), 0.0) << a << "," << b;
          continue;
        }
        // Only the lower triangle of a diagonal block is read: put garbage above it.
        S.block(k) = D.block<6, 6>(6 * a, 6 * b);
        if (a == b) S.block(k).triangularView<Eigen::StrictlyUpper>().setConstant(1e9);
      }
    for (int c = 0; c < n; ++c) EXPECT_EQ(S.diagonal_index(c), S.block_index(c, c));
    Eigen::VectorXd rhs(6 * n), x;
    for (int i = 0; i < 6 * n; ++i) rhs(i) = N(rng);
    ASSERT_TRUE(S.solve(rhs, x));
    const Eigen::VectorXd expected = D.llt().solve(rhs);
    EXPECT_LT((x - expected).lpNorm<Eigen::Infinity>(), 1e-12 * expected.lpNorm<Eigen::Infinity>()) << "n " << n;
    // A second factorisation of new values on the same pattern.
    D *= 2.0;
    for (int a = 0; a < n; ++a)
      for (int b = 0; b <= a; ++b)
        if (const int k = S.block_index(a, b); k >= 0) S.block(k) *= 2.0;
    ASSERT_TRUE(S.solve(rhs, x));
    EXPECT_LT((x - 0.5 * expected).lpNorm<Eigen::Infinity>(), 1e-12 * expected.lpNorm<Eigen::Infinity>());
  }
}

TEST(BlockSparseCameraSystem, PatternLookupsAndBadPairs) {
  BlockSparseCameraSystem S(4, {{2, 2}, {}, {3}, {}});
  EXPECT_EQ(S.num_blocks(), 4 + 2);  // the diagonal, (2,0) once, (3,2)
  EXPECT_GE(S.block_index(2, 0), 0);
  EXPECT_GE(S.block_index(3, 2), 0);
  EXPECT_EQ(S.block_index(1, 0), -1);
  EXPECT_EQ(S.block_index(3, 0), -1);
  EXPECT_EQ(S.block_index(0, 2), -1);                                                  // above the diagonal
  EXPECT_THROW(BlockSparseCameraSystem(4, {{}, {}, {1}, {}}), std::invalid_argument);  // above the diagonal
  EXPECT_THROW(BlockSparseCameraSystem(4, {{}, {1}, {}, {}}), std::invalid_argument);  // the diagonal
  EXPECT_THROW(BlockSparseCameraSystem(4, {{4}, {}, {}, {}}), std::invalid_argument);  // no such camera
  EXPECT_THROW(BlockSparseCameraSystem(4, {{}, {}}), std::invalid_argument);           // not one list per camera
  EXPECT_THROW(BlockSparseCameraSystem(0, {}), std::invalid_argument);
  Eigen::VectorXd x;
  EXPECT_THROW(S.solve(Eigen::VectorXd::Zero(6), x), std::invalid_argument);
}

TEST(BlockSparseCameraSystem, BlockIndicesWithAndWithoutTheDenseTable) {
  // 300 cameras read a dense table, 600 search their column: both give each pattern pair its own
  // block, every block to exactly one pair, and -1 off the pattern or out of range.
  std::mt19937 rng(5);
  for (const int n : {300, 600}) {
    std::set<std::pair<int, int>> pattern;
    std::vector<std::vector<int>> below(static_cast<size_t>(n));
    for (int col = 0; col + 1 < n; ++col)
      for (int k = 0; k < 3; ++k) {
        const int row = col + 1 + int(rng() % std::uint32_t(std::min(40, n - col - 1)));
        below[size_t(col)].push_back(row);
        pattern.emplace(row, col);
      }
    const BlockSparseCameraSystem S(n, below);
    EXPECT_EQ(S.num_blocks(), n + int(pattern.size()));
    std::vector<int> owner(static_cast<size_t>(S.num_blocks()), 0);
    for (int a = 0; a < n; ++a)
      for (int b = 0; b <= a; ++b) {
        const int k = S.block_index(a, b);
        if (a != b && !pattern.count({a, b})) {
          ASSERT_EQ(k, -1) << n << ": " << a << "," << b;
          continue;
        }
        ASSERT_GE(k, 0) << n << ": " << a << "," << b;
        ASSERT_LT(k, S.num_blocks());
        ++owner[size_t(k)];
      }
    EXPECT_EQ(std::count(owner.begin(), owner.end(), 1), S.num_blocks()) << n;
    EXPECT_EQ(S.block_index(n, 0), -1);
    EXPECT_EQ(S.block_index(0, n), -1);
  }
}

TEST(BlockSparseCameraSystem, NotPositiveDefiniteIsRefused) {
  BlockSparseCameraSystem S(3, {{1}, {}, {}});
  S.set_zero();
  for (int c = 0; c < 3; ++c) S.block(S.diagonal_index(c)) = Matrix6d::Identity();
  S.block(S.diagonal_index(2))(4, 4) = -1.0;
  Eigen::VectorXd x;
  EXPECT_FALSE(S.solve(Eigen::VectorXd::Ones(18), x));
}
