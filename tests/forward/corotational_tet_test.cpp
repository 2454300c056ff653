#include "mvtwin/forward/corotational_tet.h"

#include <gtest/gtest.h>
#include <Eigen/Dense>
#include <Eigen/Geometry>

#include "mvtwin/core/rng.h"
#include "mvtwin/forward/transversely_isotropic.h"

namespace mvtwin::forward {
namespace {

template <int N>
typename CorotationalTet<N>::Nodes with_midpoints(const Eigen::Matrix<double, 4, 3>& corners) {
  typename CorotationalTet<N>::Nodes X;
  X.template topRows<4>() = corners;
  if constexpr (N == 10) {
    const int e[6][2] = {{0, 1}, {1, 2}, {0, 2}, {0, 3}, {1, 3}, {2, 3}};
    for (int k = 0; k < 6; ++k) X.row(4 + k) = 0.5 * (corners.row(e[k][0]) + corners.row(e[k][1]));
  }
  return X;
}

Eigen::Matrix<double, 4, 3> reference_corners() {
  Eigen::Matrix<double, 4, 3> c;
  c << 0.1, -0.2, 0.0, 1.3, 0.1, 0.2, 0.2, 1.1, -0.1, 0.3, 0.2, 0.9;
  return c;
}

template <typename T>
class CorotationalTetTest : public ::testing::Test {};
using Orders = ::testing::Types<std::integral_constant<int, 4>, std::integral_constant<int, 10>>;
TYPED_TEST_SUITE(CorotationalTetTest, Orders);

TYPED_TEST(CorotationalTetTest, RigidMotionGivesNoForce) {
  constexpr int N = TypeParam::value;
  const auto X = with_midpoints<N>(reference_corners());
  const CorotationalTet<N> e(X, TransverselyIsotropic::anterior_leaflet().stiffness({1, 0.3, 0.1}));
  const Eigen::Matrix3d Q =
      Eigen::AngleAxisd(2.1, Eigen::Vector3d(0.3, -1, 0.4).normalized()).toRotationMatrix();
  typename CorotationalTet<N>::Nodes x =
      (X * Q.transpose()).rowwise() + Eigen::RowVector3d(5, -3, 8);
  typename CorotationalTet<N>::Vector g;
  double energy = -1;
  ASSERT_TRUE(e.evaluate(x, &g, nullptr, nullptr, &energy));
  EXPECT_LT(g.norm(), 1e-12);
  EXPECT_NEAR(energy, 0.0, 1e-12);  // roundoff of an 8 mm translation through K0
}

TYPED_TEST(CorotationalTetTest, ConsistentTangentMatchesFiniteDifferences) {
  constexpr int N = TypeParam::value;
  using Tet = CorotationalTet<N>;
  const auto X = with_midpoints<N>(reference_corners());
  const Tet e(X, TransverselyIsotropic::anterior_leaflet().stiffness({0.2, 1, 0.5}));
  Rng rng(7);
  const Eigen::Matrix3d Q =
      Eigen::AngleAxisd(1.3, Eigen::Vector3d(1, 1, 0.2).normalized()).toRotationMatrix();
  typename Tet::Nodes x = X * Q.transpose();
  for (int i = 0; i < N; ++i) {
    for (int k = 0; k < 3; ++k) x(i, k) += 0.08 * rng.normal();  // finite strain + rotation
  }
  typename Tet::Vector g;
  typename Tet::Matrix H, W;
  ASSERT_TRUE(e.evaluate(x, &g, &H, &W));
  const double h = 1e-6;
  double worst = 0.0;
  for (int j = 0; j < Tet::kDofs; ++j) {
    typename Tet::Nodes xp = x, xm = x;
    xp(j / 3, j % 3) += h;
    xm(j / 3, j % 3) -= h;
    typename Tet::Vector gp, gm;
    ASSERT_TRUE(e.evaluate(xp, &gp, nullptr, nullptr));
    ASSERT_TRUE(e.evaluate(xm, &gm, nullptr, nullptr));
    worst = std::max(worst, ((gp - gm) / (2 * h) - H.col(j)).norm());
  }
  EXPECT_LT(worst, 1e-6 * H.norm());
  // The warped tangent drops the rotation derivative: it differs under rotation and strain ...
  EXPECT_GT((H - W).norm(), 1e-4 * H.norm());
  // ... but is the exact tangent at rest.
  typename Tet::Matrix H0, W0;
  ASSERT_TRUE(e.evaluate(X, nullptr, &H0, &W0));
  EXPECT_LT((H0 - W0).norm(), 1e-10 * W0.norm());
  EXPECT_LT((W0 - e.rest_stiffness()).norm(), 1e-10 * W0.norm());
}

TYPED_TEST(CorotationalTetTest, InvertedElementIsReportedNotEvaluated) {
  constexpr int N = TypeParam::value;
  const auto X = with_midpoints<N>(reference_corners());
  const CorotationalTet<N> e(X, TransverselyIsotropic::isotropic(1, 0.3).stiffness({1, 0, 0}));
  typename CorotationalTet<N>::Nodes x = X;
  x.row(3) = X.row(0) - (X.row(3) - X.row(0));  // reflect the apex through the base
  typename CorotationalTet<N>::Vector g;
  EXPECT_FALSE(e.evaluate(x, &g, nullptr, nullptr));
  x.row(3) = X.row(0);  // flat
  EXPECT_FALSE(e.evaluate(x, &g, nullptr, nullptr));
}

TYPED_TEST(CorotationalTetTest, UniformStrainEnergyAndMass) {
  constexpr int N = TypeParam::value;
  const auto X = with_midpoints<N>(reference_corners());
  const Eigen::Matrix<double, 6, 6> C =
      TransverselyIsotropic::posterior_leaflet().stiffness({0, 1, 1});
  const CorotationalTet<N> e(X, C);
  // Linear displacement field u = G X with symmetric G (pure strain, no rotation).
  Eigen::Matrix3d G;
  G << 0.01, 0.002, -0.003, 0.002, -0.004, 0.001, -0.003, 0.001, 0.006;
  typename CorotationalTet<N>::Nodes x = X + X * G.transpose();
  double energy = 0;
  typename CorotationalTet<N>::Vector g;
  ASSERT_TRUE(e.evaluate(x, &g, nullptr, nullptr, &energy));
  Eigen::Matrix<double, 6, 1> eps;
  eps << G(0, 0), G(1, 1), G(2, 2), 2 * G(1, 2), 2 * G(0, 2), 2 * G(0, 1);
  // Small rotation of the polar decomposition is zero for symmetric G up to O(|G|^2).
  EXPECT_NEAR(energy, 0.5 * e.rest_volume() * eps.dot(C * eps), 2e-3 * energy);
  EXPECT_LT((e.centroid_strain(x) - eps).norm(), 1e-3 * eps.norm() + 1e-5);
  EXPECT_NEAR(CorotationalTet<N>::mass_fractions().sum(), 1.0, 1e-14);
  EXPECT_GT(CorotationalTet<N>::mass_fractions().minCoeff(), 0.0);
}

// The polar decomposition (scaled Newton iteration) against the SVD's over random stretches and
// rotations, from near-identity to strongly stretched and nearly flat, and refused for flat or
// inverted F.
TEST(PolarDecomposition, MatchesTheSvdAndRefusesInvertedF) {
  Rng rng(17);
  for (int trial = 0; trial < 2000; ++trial) {
    const double spread = trial < 1000 ? 0.3 : 3.0;  // mild, then strong anisotropy
    Eigen::Vector3d sigma;
    for (int k = 0; k < 3; ++k) sigma[k] = std::exp(spread * rng.normal());
    if (trial % 100 == 0) sigma[2] = 1e-6;  // nearly flat
    const Eigen::Matrix3d U =
        Eigen::AngleAxisd(6.3 * rng.uniform(),
                          Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal()).normalized())
            .toRotationMatrix();
    const Eigen::Matrix3d V =
        Eigen::AngleAxisd(6.3 * rng.uniform(),
                          Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal()).normalized())
            .toRotationMatrix();
    const Eigen::Matrix3d F = U * sigma.asDiagonal() * V.transpose();
    Eigen::Matrix3d R, S;
    ASSERT_TRUE(polar_decomposition(F, &R, &S)) << trial;
    EXPECT_LT((R - U * V.transpose()).cwiseAbs().maxCoeff(), 1e-9) << trial;
    EXPECT_LT((R * S - F).cwiseAbs().maxCoeff(), 1e-10 * F.norm()) << trial;
    EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
    EXPECT_LT((S - S.transpose()).cwiseAbs().maxCoeff(), 1e-12 * S.norm());
  }
  Eigen::Matrix3d R, S;
  EXPECT_FALSE(
      polar_decomposition(Eigen::Vector3d(1, 1, -0.5).asDiagonal().toDenseMatrix(), &R, &S));
  EXPECT_FALSE(polar_decomposition(Eigen::Matrix3d::Zero(), &R, &S));
  Eigen::Matrix3d nan = Eigen::Matrix3d::Identity();
  nan(1, 2) = std::nan("");
  EXPECT_FALSE(polar_decomposition(nan, &R, &S));
}

}  // namespace
}  // namespace mvtwin::forward
