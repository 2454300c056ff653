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

INSTANTIATE_TEST_SUITE_P(Orders, ElasticBodyPaths,
                         ::testing::Values(TetOrder::kLinear, TetOrder::kQuadratic));

}  // namespace
}  // namespace mvtwin::forward
