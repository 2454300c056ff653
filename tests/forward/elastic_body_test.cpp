#include "mvtwin/forward/elastic_body.h"

#include <gtest/gtest.h>
#include <Eigen/Dense>
#include <Eigen/Geometry>

#include "mvtwin/core/rng.h"

namespace mvtwin::forward {
namespace {

// The time integrator's path (rotations once, gradient with a fused product, matrix-free
// products, fixed-pattern assembly) against the triplet path, on a rotated and strained box of
// linear and of quadratic tetrahedra.
class ElasticBodyPaths : public ::testing::TestWithParam<TetOrder> {};

TEST_P(ElasticBodyPaths, FastPathEqualsTheTripletPath) {
  const SolidMesh solid = make_solid(box_tet_mesh({4.0, 2.0, 1.3}, {4, 2, 1}), GetParam());
  const ElasticBody body(solid, [](int) { return TransverselyIsotropic::anterior_leaflet(); });
  Rng rng(9);
  const Eigen::Matrix3d Q =
      Eigen::AngleAxisd(1.1, Eigen::Vector3d(0.2, 1.0, -0.4).normalized()).toRotationMatrix();
  const Eigen::VectorXd X = body.rest_positions();
  Eigen::VectorXd x(X.size()), p(X.size());
  for (int i = 0; i < solid.num_nodes(); ++i) {
    const Eigen::Vector3d r = X.segment<3>(3 * i);
    x.segment<3>(3 * i) =
        Q * (r + 0.02 * Eigen::Vector3d(r.y() * r.x(), -0.5 * r.z(), 0.1 * r.x())) +
        Eigen::Vector3d(3, -1, 2);
    p.segment<3>(3 * i) = Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal());
  }
  Eigen::VectorXd g_ref = Eigen::VectorXd::Zero(X.size());
  std::vector<Eigen::Triplet<double>> trip;
  double e_ref = 0.0;
  ASSERT_EQ(body.accumulate(x, &g_ref, &trip, Tangent::kWarped, &e_ref), -1);
  Eigen::SparseMatrix<double> K(X.size(), X.size());
  K.setFromTriplets(trip.begin(), trip.end());

  Eigen::VectorXd g, Kp;
  ElementRotations rot;
  double e = 0.0;
  ASSERT_EQ(body.gradient(x, &g, &rot, &e, &p, &Kp), -1);
  const double scale = g_ref.cwiseAbs().maxCoeff();
  ASSERT_GT(scale, 0.0);
  EXPECT_LT((g - g_ref).cwiseAbs().maxCoeff(), 1e-12 * scale);
  EXPECT_NEAR(e, e_ref, 1e-12 * e_ref);
  const Eigen::VectorXd Kp_ref = K * p;
  EXPECT_LT((Kp - Kp_ref).cwiseAbs().maxCoeff(), 1e-12 * Kp_ref.cwiseAbs().maxCoeff());
  Eigen::VectorXd y = Eigen::VectorXd::Zero(X.size());
  body.tangent_times(rot, p, &y);
  EXPECT_LT((y - Kp_ref).cwiseAbs().maxCoeff(), 1e-12 * Kp_ref.cwiseAbs().maxCoeff());

  // Fixed-pattern assembly with every node free equals the triplet matrix (times the scale).
  SymmetricBlockMatrix A(std::vector<char>(solid.num_nodes(), 1), body.element_cliques());
  A.set_zero();
  body.assemble_tangent(rot, 2.5, &A);
  const Eigen::MatrixXd dense = 2.5 * Eigen::MatrixXd(K);
  EXPECT_LT((Eigen::MatrixXd(A.lower()) - Eigen::MatrixXd(dense.triangularView<Eigen::Lower>()))
                .cwiseAbs()
                .maxCoeff(),
            1e-10 * dense.cwiseAbs().maxCoeff());

  // An inverted element is reported by the fast path too.
  Eigen::VectorXd flat = x;
  for (int i = 0; i < solid.num_nodes(); ++i) flat[3 * i + 2] = -flat[3 * i + 2];
  EXPECT_GE(body.gradient(flat, &g, &rot), 0);
}

// The inversion guard: nothing above j0; below it, energy and gradient agree (central
// differences), the energy grows without bound as the elements flatten, and the product with
// the tangent equals the assembled tangent's (both carry the guard's Gauss-Newton term).
TEST_P(ElasticBodyPaths, InversionGuardIsABarrierWithConsistentDerivatives) {
  const SolidMesh solid = make_solid(box_tet_mesh({2.0, 2.0, 1.0}, {1, 1, 1}), GetParam());
  ElasticBody body(solid, [](int) { return TransverselyIsotropic::posterior_leaflet(); });
  const Eigen::VectorXd X = body.rest_positions();
  auto squash = [&](double s) {  // z scaled by s: det F = s in every element, plus a shear
    Eigen::VectorXd x = X;
    for (int i = 0; i < solid.num_nodes(); ++i) {
      x[3 * i + 2] *= s;
      x[3 * i] += 0.3 * X[3 * i + 2];
    }
    return x;
  };
  Eigen::VectorXd g, g0;
  ElementRotations rot;
  double e_on = 0, e_off = 0;
  // Above j0: identical with and without the guard.
  body.set_inversion_guard(0.0);
  ASSERT_EQ(body.gradient(squash(0.5), &g0, &rot, &e_off), -1);
  body.set_inversion_guard(0.2);
  ASSERT_EQ(body.gradient(squash(0.5), &g, &rot, &e_on), -1);
  EXPECT_EQ(e_on, e_off);
  EXPECT_TRUE(rot.guards.empty());
  // Below: energy added, growing without bound.
  double previous = 0.0;
  for (double s : {0.15, 0.05, 1e-3, 1e-6}) {
    body.set_inversion_guard(0.0);
    ASSERT_EQ(body.gradient(squash(s), &g0, &rot, &e_off), -1);
    body.set_inversion_guard(0.2);
    ASSERT_EQ(body.gradient(squash(s), &g, &rot, &e_on), -1);
    EXPECT_EQ(static_cast<int>(rot.guards.size()), solid.num_elements());
    EXPECT_GT(e_on - e_off, previous) << "s " << s;
    previous = e_on - e_off;
  }
  // Unbounded (logarithmically in energy, as 1/J in force) as J -> 0.
  body.set_inversion_guard(0.0);
  ASSERT_EQ(body.gradient(squash(1e-12), &g0, &rot, &e_off), -1);
  body.set_inversion_guard(0.2);
  ASSERT_EQ(body.gradient(squash(1e-12), &g, &rot, &e_on), -1);
  EXPECT_GT(e_on - e_off, 1.5 * previous);
  EXPECT_GT((g - g0).cwiseAbs().maxCoeff(), 1e6 * g0.cwiseAbs().maxCoeff());
  // The guard's gradient against central differences of the guard's energy at s = 0.1 (the
  // co-rotational gradient itself is not exactly an energy gradient for anisotropic material).
  auto guard_part = [&](const Eigen::VectorXd& xq, Eigen::VectorXd* gq) {
    Eigen::VectorXd ga, gb;
    ElementRotations r2;
    double ea = 0, eb = 0;
    body.set_inversion_guard(0.2);
    EXPECT_EQ(body.gradient(xq, &ga, &r2, &ea), -1);
    body.set_inversion_guard(0.0);
    EXPECT_EQ(body.gradient(xq, &gb, &r2, &eb), -1);
    body.set_inversion_guard(0.2);
    if (gq) *gq = ga - gb;
    return ea - eb;
  };
  const Eigen::VectorXd x = squash(0.1);
  Eigen::VectorXd gg;
  guard_part(x, &gg);
  ASSERT_GT(gg.cwiseAbs().maxCoeff(), 0.0);
  const double h = 1e-7;
  double worst = 0.0;
  for (int d = 0; d < x.size(); ++d) {
    Eigen::VectorXd xp = x, xm = x;
    xp[d] += h;
    xm[d] -= h;
    worst = std::max(
        worst, std::abs((guard_part(xp, nullptr) - guard_part(xm, nullptr)) / (2 * h) - gg[d]));
  }
  EXPECT_LT(worst, 1e-5 * gg.cwiseAbs().maxCoeff());
  ASSERT_EQ(body.gradient(x, &g, &rot, &e_on), -1);
  // Product and assembly agree, guard included, and the guard stiffens the element.
  Rng rng(4);
  Eigen::VectorXd p(x.size());
  for (int i = 0; i < p.size(); ++i) p[i] = rng.normal();
  Eigen::VectorXd y = Eigen::VectorXd::Zero(x.size());
  body.tangent_times(rot, p, &y);
  SymmetricBlockMatrix A(std::vector<char>(solid.num_nodes(), 1), body.element_cliques());
  A.set_zero();
  body.assemble_tangent(rot, 1.0, &A);
  Eigen::VectorXd Ap;
  A.multiply(p, &Ap);
  EXPECT_LT((y - Ap).cwiseAbs().maxCoeff(), 1e-10 * Ap.cwiseAbs().maxCoeff());
  body.set_inversion_guard(0.0);
  ElementRotations r0;
  ASSERT_EQ(body.gradient(x, &g0, &r0), -1);
  Eigen::VectorXd y0 = Eigen::VectorXd::Zero(x.size());
  body.tangent_times(r0, p, &y0);
  EXPECT_GT(p.dot(y), p.dot(y0));
}

INSTANTIATE_TEST_SUITE_P(Orders, ElasticBodyPaths,
                         ::testing::Values(TetOrder::kLinear, TetOrder::kQuadratic));

}  // namespace
}  // namespace mvtwin::forward
