#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "mvtwin/inverse/calibration.h"

namespace mvtwin::inverse {
namespace {

CalibrationResult with_specs(int n) {
  CalibrationResult r;
  for (int i = 0; i < n; ++i)
    r.specs.push_back({"p" + std::to_string(i), "g", "1", 0, 2, 1, 0.05, 1});
  return r;
}

TEST(Uncertainty, LinearLeastSquaresCovariance) {
  // For residuals linear in the parameters with iid noise sigma, cov = sigma^2 (J^T J)^-1.
  std::mt19937 gen(3);
  std::normal_distribution<double> nd;
  Eigen::MatrixXd J(200, 3);
  for (Eigen::Index i = 0; i < J.size(); ++i) J.data()[i] = nd(gen);
  J.col(2) = 0.9 * J.col(0) + 0.1 * J.col(2);  // strongly correlated with the first
  CalibrationResult r = with_specs(3);
  fill_uncertainty(J, 0.5, &r);
  const Eigen::MatrixXd expected = 0.25 * (J.transpose() * J).inverse();
  EXPECT_LT((r.covariance - expected).norm(), 1e-10 * expected.norm());
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(r.sd[i], std::sqrt(expected(i, i)), 1e-12);
    EXPECT_NEAR(r.correlation(i, i), 1.0, 1e-12);
  }
  EXPECT_GT(std::abs(r.correlation(0, 2)), 0.9) << "the trade-off shows";
  EXPECT_LT(std::abs(r.correlation(0, 1)), 0.3);
  EXPECT_TRUE(r.identified[1]);
}

TEST(Uncertainty, ParametersTheDataDoNotSeeAreUnidentified) {
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(50, 3);
  J.col(0).setLinSpaced(50, 1.0, 2.0);
  J.col(1) = J.col(0);        // only their sum is seen
  J.col(2).setConstant(0.0);  // not seen at all
  CalibrationResult r = with_specs(3);
  fill_uncertainty(J, 0.3, &r);
  EXPECT_FALSE(r.identified[0]);
  EXPECT_FALSE(r.identified[1]);
  EXPECT_FALSE(r.identified[2]);
  EXPECT_TRUE(std::isnan(r.sd[2]));
  // A well-seen parameter with a large sd is unidentified too (sd above its scale, 0.05).
  Eigen::MatrixXd K = Eigen::MatrixXd::Constant(10, 1, 1.0);
  CalibrationResult q = with_specs(1);
  fill_uncertainty(K, 1.0, &q);  // sd = 1/sqrt(10) = 0.32
  EXPECT_NEAR(q.sd[0], 1.0 / std::sqrt(10.0), 1e-12);
  EXPECT_FALSE(q.identified[0]);
  fill_uncertainty(100.0 * K, 1.0, &q);  // sd = 0.0032
  EXPECT_TRUE(q.identified[0]);
}

}  // namespace
}  // namespace mvtwin::inverse
