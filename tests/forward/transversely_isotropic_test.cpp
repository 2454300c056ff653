#include "mvtwin/forward/transversely_isotropic.h"

#include <gtest/gtest.h>
#include <Eigen/Dense>
#include <Eigen/Geometry>

namespace mvtwin::forward {
namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;

// Strain response to a unit stress component, from the stiffness (not the compliance).
Vec6 strain_for_stress(const Eigen::Matrix<double, 6, 6>& C, int component) {
  return C.lu().solve(Vec6::Unit(component));
}

class TransverselyIsotropicTest : public ::testing::TestWithParam<TransverselyIsotropic> {};

TEST_P(TransverselyIsotropicTest, StiffnessReproducesTheEngineeringConstants) {
  const TransverselyIsotropic m = GetParam();
  std::string err;
  ASSERT_TRUE(m.is_valid(&err)) << err;
  const Eigen::Matrix<double, 6, 6> C = m.stiffness_local();
  // Uniaxial stress along the fibre: eps1 = 1/E1, eps2 = eps3 = -nu12/E1.
  Vec6 e = strain_for_stress(C, 0);
  EXPECT_NEAR(e[0], 1.0 / m.e_fibre, 1e-12);
  EXPECT_NEAR(e[1], -m.nu_fibre / m.e_fibre, 1e-12);
  EXPECT_NEAR(e[2], -m.nu_fibre / m.e_fibre, 1e-12);
  // Across: eps2 = 1/E2, eps3 = -nu23/E2, eps1 = -nu21/E2 = -nu12/E1.
  e = strain_for_stress(C, 1);
  EXPECT_NEAR(e[1], 1.0 / m.e_cross, 1e-12);
  EXPECT_NEAR(e[2], -m.nu_cross / m.e_cross, 1e-12);
  EXPECT_NEAR(e[0], -m.nu_fibre / m.e_fibre, 1e-12);
  // Shears: gamma12 = tau/G12, gamma13 = tau/G12, gamma23 = tau/G23 with G23 = E2/(2(1+nu23)).
  EXPECT_NEAR(strain_for_stress(C, 5)[5], 1.0 / m.g_fibre, 1e-12);
  EXPECT_NEAR(strain_for_stress(C, 4)[4], 1.0 / m.g_fibre, 1e-12);
  EXPECT_NEAR(strain_for_stress(C, 3)[3], 2.0 * (1.0 + m.nu_cross) / m.e_cross, 1e-12);
  // Symmetric positive definite.
  EXPECT_LT((C - C.transpose()).norm(), 1e-9 * C.norm());
  EXPECT_EQ(C.llt().info(), Eigen::Success);
}

TEST_P(TransverselyIsotropicTest, RotatedStiffnessFollowsTheFibre) {
  const TransverselyIsotropic m = GetParam();
  const Eigen::Vector3d fibre = Eigen::Vector3d(1.0, 2.0, -0.5).normalized();
  const Eigen::Matrix<double, 6, 6> C = m.stiffness(fibre);
  // Uniaxial stress along the fibre gives strain 1/E1 along it and -nu12/E1 across.
  const Eigen::Matrix3d sigma = fibre * fibre.transpose();
  Vec6 s;
  s << sigma(0, 0), sigma(1, 1), sigma(2, 2), sigma(1, 2), sigma(0, 2), sigma(0, 1);
  const Vec6 e = C.lu().solve(s);
  Eigen::Matrix3d eps;
  eps << e[0], e[5] / 2, e[4] / 2, e[5] / 2, e[1], e[3] / 2, e[4] / 2, e[3] / 2, e[2];
  EXPECT_NEAR(fibre.dot(eps * fibre), 1.0 / m.e_fibre, 1e-12);
  const Eigen::Vector3d across = fibre.cross(Eigen::Vector3d::UnitZ()).normalized();
  EXPECT_NEAR(across.dot(eps * across), -m.nu_fibre / m.e_fibre, 1e-12);
  // Transverse isotropy: the choice of the 2-3 axes does not matter.
  const Eigen::Matrix<double, 6, 6> C2 = m.stiffness(-fibre);
  EXPECT_LT((C - C2).norm(), 1e-10 * C.norm());
}

INSTANTIATE_TEST_SUITE_P(PaperLeaflets, TransverselyIsotropicTest,
                         ::testing::Values(TransverselyIsotropic::anterior_leaflet(),
                                           TransverselyIsotropic::posterior_leaflet(),
                                           TransverselyIsotropic::isotropic(6.233, 0.488)));

TEST(TransverselyIsotropic, IsotropicCaseMatchesLame) {
  const double E = 3.0, nu = 0.3;
  const auto C = TransverselyIsotropic::isotropic(E, nu).stiffness_local();
  const double lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), mu = E / (2 * (1 + nu));
  EXPECT_NEAR(C(0, 0), lambda + 2 * mu, 1e-12);
  EXPECT_NEAR(C(0, 1), lambda, 1e-12);
  EXPECT_NEAR(C(3, 3), mu, 1e-12);
}

TEST(TransverselyIsotropic, RejectsImpossibleConstants) {
  std::string err;
  EXPECT_FALSE((TransverselyIsotropic{-1, 1, 1, 0.3, 0.3}).is_valid(&err));
  EXPECT_FALSE((TransverselyIsotropic{1, 1, 1, 0.3, 1.2}).is_valid(&err));
  // nu12 so large that the compliance is indefinite: 1 - nu23 - 2 nu12^2 E2/E1 < 0.
  EXPECT_FALSE((TransverselyIsotropic{1, 10, 1, 0.5, 0.49}).is_valid(&err));
  EXPECT_NE(err.find("positive definite"), std::string::npos);
}

}  // namespace
}  // namespace mvtwin::forward
