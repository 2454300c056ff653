#include "mvtwin/forward/symmetric_block_matrix.h"

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "mvtwin/core/error.h"
#include "mvtwin/core/rng.h"

namespace mvtwin::forward {
namespace {

Eigen::MatrixXd random_spd(int m, Rng* rng) {
  Eigen::MatrixXd B(m, m);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) B(i, j) = rng->normal();
  return B * B.transpose() + Eigen::MatrixXd::Identity(m, m);
}

// Cliques of different sizes (overlapping, with prescribed nodes among them) assembled into the
// fixed pattern equal the same blocks added into a dense matrix over the free dofs; the product
// equals the dense product.
TEST(SymmetricBlockMatrix, AssemblyAndProductMatchADenseMatrix) {
  Rng rng(5);
  const int n = 12;
  std::vector<char> free(n, 1);
  free[3] = free[8] = 0;
  const std::vector<std::vector<int>> cliques = {{0, 1, 2, 3},   {2, 4, 5}, {5, 6, 7, 8, 9},
                                                 {9, 10, 11, 0}, {4, 2},    {11, 10}};
  SymmetricBlockMatrix A(free, cliques);
  ASSERT_EQ(A.rows(), 3 * 10);
  std::vector<int> row(n, -1);
  for (int i = 0, r = 0; i < n; ++i) {
    if (free[i]) {
      row[i] = r;
      r += 3;
    }
    EXPECT_EQ(A.first_row(i), row[i]);
  }
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(30, 30);
  for (int round = 0; round < 2; ++round) {  // twice: set_zero() must clear
    A.set_zero();
    dense.setZero();
    for (size_t c = 0; c < cliques.size(); ++c) {
      const int m = static_cast<int>(cliques[c].size());
      const Eigen::MatrixXd K = random_spd(3 * m, &rng);
      const double s = 0.5 + c;
      A.add_clique(static_cast<int>(c), K, s);
      for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j) {
          const int a = row[cliques[c][i]], b = row[cliques[c][j]];
          if (a >= 0 && b >= 0) dense.block<3, 3>(a, b) += s * K.block<3, 3>(3 * i, 3 * j);
        }
    }
    Eigen::Matrix3d B = random_spd(3, &rng);
    A.add_diagonal_block(6, B);
    A.add_diagonal_block(3, B);  // prescribed: ignored
    dense.block<3, 3>(row[6], row[6]) += B;
    Eigen::VectorXd d(n);
    for (int i = 0; i < n; ++i) d[i] = 1.0 + i;
    A.add_diagonal(d);
    for (int i = 0; i < n; ++i)
      if (row[i] >= 0) dense.block<3, 3>(row[i], row[i]) += d[i] * Eigen::Matrix3d::Identity();
    const Eigen::MatrixXd lower = Eigen::MatrixXd(A.lower());
    EXPECT_LT((lower - Eigen::MatrixXd(dense.triangularView<Eigen::Lower>())).cwiseAbs().maxCoeff(),
              1e-12);
    Eigen::VectorXd x(30), y;
    for (int i = 0; i < 30; ++i) x[i] = rng.normal();
    A.multiply(x, &y);
    EXPECT_LT((y - dense * x).cwiseAbs().maxCoeff(), 1e-11);
  }
}

TEST(SymmetricBlockMatrix, BadInputIsNamed) {
  EXPECT_THROW(SymmetricBlockMatrix({1, 1}, {{0, 2}}), Error);     // node out of range
  EXPECT_THROW(SymmetricBlockMatrix({1, 1, 1}, {{0, 1}}), Error);  // free node 2 in no clique
}

}  // namespace
}  // namespace mvtwin::forward
