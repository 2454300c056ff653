// Patch test: on a mesh of distorted elements, prescribing a linear displacement field on the
// boundary must reproduce it exactly inside, with the uniform strain (and stress) in every
// element. Linear and quadratic tetrahedra, anisotropic material with an oblique fibre.
#include <gtest/gtest.h>
#include <Eigen/SparseCholesky>

#include "mvtwin/core/rng.h"
#include "mvtwin/forward/elastic_body.h"

namespace mvtwin::forward {
namespace {

// (order, curved): quadratic elements also with their mid-edge nodes moved off the edges
// (isoparametric, as on the curved leaflet).
class PatchTest : public ::testing::TestWithParam<std::tuple<TetOrder, bool>> {};

TEST_P(PatchTest, LinearFieldIsReproducedExactly) {
  const auto [order, curved] = GetParam();
  TetMesh box = box_tet_mesh({3.0, 3.0, 2.0}, {3, 3, 2});
  // Distort the interior vertices.
  Rng rng(11);
  auto on_boundary = [&](const Eigen::RowVector3d& p) {
    return p.x() < 1e-9 || p.x() > 3 - 1e-9 || p.y() < 1e-9 || p.y() > 3 - 1e-9 || p.z() < 1e-9 ||
           p.z() > 2 - 1e-9;
  };
  int moved = 0;
  for (Eigen::Index i = 0; i < box.V.rows(); ++i) {
    if (on_boundary(box.V.row(i))) continue;
    box.V.row(i) += Eigen::RowVector3d(rng.uniform(-0.25, 0.25), rng.uniform(-0.25, 0.25),
                                       rng.uniform(-0.2, 0.2));
    ++moved;
  }
  ASSERT_GT(moved, 0);
  const Eigen::Vector3d fibre = Eigen::Vector3d(1.0, 0.7, 0.3).normalized();
  for (Eigen::Index e = 0; e < box.T.rows(); ++e) box.fibre.row(e) = fibre.transpose();
  SolidMesh solid = make_solid(box, order);
  if (curved) {
    for (int i = solid.corner_nodes; i < solid.num_nodes(); ++i) {
      if (on_boundary(solid.V.row(i))) continue;  // keep the box's faces flat
      solid.V.row(i) += Eigen::RowVector3d(rng.uniform(-0.08, 0.08), rng.uniform(-0.08, 0.08),
                                           rng.uniform(-0.08, 0.08));
    }
  }
  const ElasticBody body(solid, [](int) { return TransverselyIsotropic::anterior_leaflet(); });
  const Eigen::VectorXd X = body.rest_positions();
  const int ndof = body.num_dofs();

  // Stiffness at rest (the co-rotational element's small-strain limit).
  Eigen::VectorXd g = Eigen::VectorXd::Zero(ndof);
  std::vector<Eigen::Triplet<double>> trip;
  ASSERT_EQ(body.accumulate(X, &g, &trip, Tangent::kWarped), -1);
  Eigen::SparseMatrix<double> K(ndof, ndof);
  K.setFromTriplets(trip.begin(), trip.end());

  // u = G X + c with a general (non-symmetric: includes an infinitesimal rotation) G.
  Eigen::Matrix3d G;
  G << 0.010, 0.004, -0.002, -0.001, -0.006, 0.003, 0.005, 0.002, 0.008;
  const Eigen::Vector3d c(0.1, -0.2, 0.05);
  Eigen::VectorXd u_exact(ndof);
  std::vector<int> interior;
  for (int i = 0; i < solid.num_nodes(); ++i) {
    u_exact.segment<3>(3 * i) = G * X.segment<3>(3 * i) + c;
    if (!on_boundary(solid.V.row(i))) interior.push_back(i);
  }
  ASSERT_FALSE(interior.empty());
  // Solve K_ii u_i = -K_ib u_b.
  std::vector<int> dof_of(ndof, -1);
  int ni = 0;
  for (int i : interior)
    for (int k = 0; k < 3; ++k) dof_of[3 * i + k] = ni++;
  std::vector<Eigen::Triplet<double>> tii;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(ni);
  for (int col = 0; col < K.outerSize(); ++col) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(K, col); it; ++it) {
      const int r = dof_of[it.row()], cc = dof_of[it.col()];
      if (r < 0) continue;
      if (cc >= 0) {
        tii.emplace_back(r, cc, it.value());
      } else {
        rhs[r] -= it.value() * u_exact[it.col()];
      }
    }
  }
  Eigen::SparseMatrix<double> Kii(ni, ni);
  Kii.setFromTriplets(tii.begin(), tii.end());
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(Kii);
  ASSERT_EQ(ldlt.info(), Eigen::Success);
  const Eigen::VectorXd ui = ldlt.solve(rhs);
  double worst = 0.0;
  for (int i : interior)
    for (int k = 0; k < 3; ++k)
      worst = std::max(worst, std::abs(ui[dof_of[3 * i + k]] - u_exact[3 * i + k]));
  // Curved elements pass to the 4-point rule's accuracy only (det J and the adjugate are
  // cubic): here mid-edge nodes are up to 8 % of an edge off, more than the leaflet's ~3 %.
  const double u_scale = u_exact.cwiseAbs().maxCoeff();
  EXPECT_LT(worst, (curved ? 1e-3 : 1e-10) * u_scale)
      << "interior displacement off the linear field";

  // The internal forces of the exact field vanish at interior nodes (equilibrium) ...
  const Eigen::VectorXd f = K * u_exact;
  double fmax = 0.0, fscale = 0.0;
  for (int d = 0; d < ndof; ++d) {
    fscale = std::max(fscale, std::abs(f[d]));
    if (dof_of[d] >= 0) fmax = std::max(fmax, std::abs(f[d]));
  }
  EXPECT_LT(fmax, (curved ? 1e-2 : 1e-10) * fscale);
  // ... and every element strains uniformly by the symmetric part of G (tiny G: the polar
  // rotation's second-order term is negligible).
  const Eigen::Matrix3d Gs = 1e-4 * G;
  const Eigen::Matrix3d eps = 0.5 * (Gs + Gs.transpose());
  Eigen::Matrix<double, 6, 1> ev;
  ev << eps(0, 0), eps(1, 1), eps(2, 2), 2 * eps(1, 2), 2 * eps(0, 2), 2 * eps(0, 1);
  Eigen::VectorXd x(ndof);
  for (int i = 0; i < solid.num_nodes(); ++i)
    x.segment<3>(3 * i) = X.segment<3>(3 * i) + Gs * X.segment<3>(3 * i);
  double energy = 0.0;
  ElementRotations rot;
  Eigen::VectorXd gg;
  ASSERT_EQ(body.gradient(x, &gg, &rot, &energy), -1);
  // The body's volume (curved elements: moved mid-edge nodes inside keep the total).
  double volume = 0.0;
  for (Eigen::Index e = 0; e < box.T.rows(); ++e) volume += box.volume(static_cast<int>(e));
  EXPECT_NEAR(body.lumped_mass(1.0).sum(), volume, (curved ? 1e-4 : 1e-9) * volume);
  const Eigen::Matrix<double, 6, 6> C = TransverselyIsotropic::anterior_leaflet().stiffness(fibre);
  EXPECT_NEAR(energy, 0.5 * volume * ev.dot(C * ev), (curved ? 1e-3 : 1e-6) * energy);
}

INSTANTIATE_TEST_SUITE_P(Orders, PatchTest,
                         ::testing::Values(std::make_tuple(TetOrder::kLinear, false),
                                           std::make_tuple(TetOrder::kQuadratic, false),
                                           std::make_tuple(TetOrder::kQuadratic, true)));

}  // namespace
}  // namespace mvtwin::forward
