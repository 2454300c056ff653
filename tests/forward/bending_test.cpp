// Bending benchmarks built from the production tetrahedra: the thin strip that locks with
// linear tetrahedra at nu = 0.488 (Mansi et al. 2012, Sec. 2.3), and the large-deflection
// cantilever against the elastica.
#include <cmath>
#include <iostream>
#include <map>

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseLU>

#include "mvtwin/forward/elastic_body.h"

namespace mvtwin::forward {
namespace {

struct Face {
  int a, b, c;
};

// Boundary triangles of a linear tet mesh whose three vertices satisfy `on`.
template <typename Pred>
std::vector<Face> boundary_faces(const TetMesh& m, Pred on) {
  std::map<std::array<int, 3>, int> count;
  for (Eigen::Index e = 0; e < m.T.rows(); ++e) {
    const int f[4][3] = {{0, 1, 2}, {0, 1, 3}, {0, 2, 3}, {1, 2, 3}};
    for (const auto& ff : f) {
      std::array<int, 3> k = {m.T(e, ff[0]), m.T(e, ff[1]), m.T(e, ff[2])};
      std::sort(k.begin(), k.end());
      ++count[k];
    }
  }
  std::vector<Face> out;
  for (const auto& [k, n] : count) {
    if (n == 1 && on(m.V.row(k[0])) && on(m.V.row(k[1])) && on(m.V.row(k[2])))
      out.push_back({k[0], k[1], k[2]});
  }
  return out;
}

// Consistent nodal loads of a uniform traction t (force per area) on flat triangles: corners
// get A/3 each for linear elements; for quadratic ones the corners get 0 and the mid-edge
// nodes A/3 each.
Eigen::VectorXd traction_load(const SolidMesh& s, const TetMesh& m, const std::vector<Face>& faces,
                              const Eigen::Vector3d& t) {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * s.num_nodes());
  for (const Face& fc : faces) {
    const Eigen::Vector3d p0 = m.V.row(fc.a), p1 = m.V.row(fc.b), p2 = m.V.row(fc.c);
    const double area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
    const int nodes[3][2] = {{fc.a, fc.b}, {fc.b, fc.c}, {fc.a, fc.c}};
    for (int k = 0; k < 3; ++k) {
      const int n = s.order == TetOrder::kLinear ? (k == 0   ? fc.a
                                                    : k == 1 ? fc.b
                                                             : fc.c)
                                                 : s.mid_node(nodes[k][0], nodes[k][1]);
      f.segment<3>(3 * n) += area / 3.0 * t;
    }
  }
  return f;
}

struct Cantilever {
  TetMesh linear;
  SolidMesh solid;
  std::vector<bool> fixed;  // per dof
  std::vector<int> tip;     // nodes on the free end
};

// Root conditions at x = 0. kFull fixes every node of the root face. kBeam is what
// Euler-Bernoulli theory assumes: the root section stays plane and normal to the axis
// (u_x = 0 on the face) but contracts freely (z fixed only on the mid-plane, y only on the
// centre line); with nu = 0.488 a full clamp adds ~8 % stiffness that beam theory ignores.
enum class Root { kFull, kBeam };

Cantilever cantilever(const Eigen::Vector3d& size, const std::array<int, 3>& cells, TetOrder order,
                      Root root = Root::kFull) {
  Cantilever c;
  c.linear = box_tet_mesh(size, cells);
  c.solid = make_solid(c.linear, order);
  c.fixed.assign(3 * c.solid.num_nodes(), false);
  // The root nodes closest to the mid-plane (both faces of a single linear layer tie).
  double nearest = 1e30;
  for (int i = 0; i < c.solid.num_nodes(); ++i) {
    if (std::abs(c.solid.V(i, 0)) < 1e-9)
      nearest = std::min(nearest, std::abs(c.solid.V(i, 2) - 0.5 * size.z()));
  }
  for (int i = 0; i < c.solid.num_nodes(); ++i) {
    if (std::abs(c.solid.V(i, 0)) < 1e-9) {
      c.fixed[3 * i] = true;
      c.fixed[3 * i + 1] = root == Root::kFull || std::abs(c.solid.V(i, 1) - 0.5 * size.y()) < 1e-9;
      c.fixed[3 * i + 2] = root == Root::kFull ||
                           std::abs(std::abs(c.solid.V(i, 2) - 0.5 * size.z()) - nearest) < 1e-9;
    }
    if (std::abs(c.solid.V(i, 0) - size.x()) < 1e-9) c.tip.push_back(i);
  }
  return c;
}

// Index map of the free dofs.
std::vector<int> free_dofs(const std::vector<bool>& fixed) {
  std::vector<int> idx;
  for (size_t i = 0; i < fixed.size(); ++i) {
    if (!fixed[i]) idx.push_back(static_cast<int>(i));
  }
  return idx;
}

Eigen::SparseMatrix<double> reduce(const std::vector<Eigen::Triplet<double>>& trip,
                                   const std::vector<bool>& fixed,
                                   const std::vector<int>& map_to_free, int n_free) {
  std::vector<Eigen::Triplet<double>> r;
  r.reserve(trip.size());
  for (const auto& t : trip) {
    if (!fixed[t.row()] && !fixed[t.col()])
      r.emplace_back(map_to_free[t.row()], map_to_free[t.col()], t.value());
  }
  Eigen::SparseMatrix<double> K(n_free, n_free);
  K.setFromTriplets(r.begin(), r.end());
  return K;
}

// Mean tip displacement under a linear static solve K0 u = f.
Eigen::Vector3d linear_tip_displacement(const Cantilever& c, const TransverselyIsotropic& mat,
                                        const Eigen::VectorXd& f) {
  const ElasticBody body(c.solid, [&](int) { return mat; });
  const Eigen::VectorXd x0 = body.rest_positions();
  std::vector<Eigen::Triplet<double>> trip;
  EXPECT_EQ(body.accumulate(x0, nullptr, &trip, Tangent::kWarped), -1);
  const std::vector<int> fr = free_dofs(c.fixed);
  std::vector<int> to_free(c.fixed.size(), -1);
  for (size_t i = 0; i < fr.size(); ++i) to_free[fr[i]] = static_cast<int>(i);
  const Eigen::SparseMatrix<double> K = reduce(trip, c.fixed, to_free, static_cast<int>(fr.size()));
  Eigen::VectorXd rhs(fr.size());
  for (size_t i = 0; i < fr.size(); ++i) rhs[i] = f[fr[i]];
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(K);
  EXPECT_EQ(ldlt.info(), Eigen::Success);
  const Eigen::VectorXd u = ldlt.solve(rhs);
  EXPECT_LT((K * u - rhs).norm(), 1e-8 * rhs.norm())
      << "singular system (a rigid-body mode left free?)";
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();
  for (int n : c.tip) {
    for (int k = 0; k < 3; ++k) tip[k] += to_free[3 * n + k] >= 0 ? u[to_free[3 * n + k]] : 0.0;
  }
  return tip / static_cast<double>(c.tip.size());
}

// Mansi et al. 2012, Sec. 2.3 / issue 3: strip 20 x 5 x 1.3 mm, E = 6.233 MPa, nu = 0.488, small
// uniform pressure p on the top: Euler-Bernoulli tip deflection 3 p L^4 / (2 E t^3). Mesh 20 x 4
// cells in plane, 1 or 2 layers through the thickness. The production (quadratic) element must be
// within 5 %; the plain linear tetrahedron is reported, and must lock.
TEST(ThinStripBending, QuadraticTetrahedraDoNotLockLinearOnesDo) {
  const double L = 20, w = 5, t = 1.3, E = 6.233, nu = 0.488, p = 1e-5;
  const double w_eb = 3 * p * std::pow(L, 4) / (2 * E * std::pow(t, 3));
  const TransverselyIsotropic mat = TransverselyIsotropic::isotropic(E, nu);
  for (int layers : {1, 2}) {
    for (TetOrder order : {TetOrder::kQuadratic, TetOrder::kLinear}) {
      double ratio[2] = {0, 0};
      for (Root root : {Root::kBeam, Root::kFull}) {
        const Cantilever c = cantilever({L, w, t}, {20, 4, layers}, order, root);
        const auto top =
            boundary_faces(c.linear, [&](const auto& v) { return std::abs(v[2] - t) < 1e-9; });
        const Eigen::VectorXd f = traction_load(c.solid, c.linear, top, {0, 0, -p});
        EXPECT_NEAR(f.sum(), -p * L * w, 1e-12);
        ratio[root == Root::kFull] = -linear_tip_displacement(c, mat, f).z() / w_eb;
      }
      const bool quadratic = order == TetOrder::kQuadratic;
      std::cout << (quadratic ? "quadratic" : "linear   ") << " tets, " << layers
                << " layer(s), 20x4 cells, nu 0.488: tip / Euler-Bernoulli = " << ratio[0]
                << " (beam root), " << ratio[1] << " (fully clamped root)\n";
      if (quadratic) {
        EXPECT_NEAR(ratio[0], 1.0, 0.05) << layers << " layers";
        EXPECT_LT(ratio[1], ratio[0]);  // the full clamp only adds stiffness
      } else {
        EXPECT_GT(ratio[0], 0.0);
        EXPECT_LT(ratio[0], 0.5) << "linear tetrahedra were expected to lock";
      }
    }
  }
}

// Newton with load steps on the consistent tangent; returns the mean tip displacement.
Eigen::Vector3d elastica_tip(const Cantilever& c, const TransverselyIsotropic& mat,
                             const Eigen::VectorXd& f_total, int steps, int* iterations) {
  const ElasticBody body(c.solid, [&](int) { return mat; });
  Eigen::VectorXd x = body.rest_positions();
  const Eigen::VectorXd x0 = x;
  const std::vector<int> fr = free_dofs(c.fixed);
  std::vector<int> to_free(c.fixed.size(), -1);
  for (size_t i = 0; i < fr.size(); ++i) to_free[fr[i]] = static_cast<int>(i);
  *iterations = 0;
  for (int s = 1; s <= steps; ++s) {
    const Eigen::VectorXd f = f_total * (static_cast<double>(s) / steps);
    for (int it = 0; it < 30; ++it) {
      Eigen::VectorXd g = Eigen::VectorXd::Zero(x.size());
      std::vector<Eigen::Triplet<double>> trip;
      EXPECT_EQ(body.accumulate(x, &g, &trip, Tangent::kConsistent), -1);
      Eigen::VectorXd r(fr.size());
      for (size_t i = 0; i < fr.size(); ++i) r[i] = g[fr[i]] - f[fr[i]];
      if (r.norm() < 1e-9 * f_total.norm()) break;
      const Eigen::SparseMatrix<double> K =
          reduce(trip, c.fixed, to_free, static_cast<int>(fr.size()));
      Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(K);
      EXPECT_EQ(lu.info(), Eigen::Success);
      const Eigen::VectorXd dx = lu.solve(-r);
      for (size_t i = 0; i < fr.size(); ++i) x[fr[i]] += dx[i];
      ++*iterations;
    }
  }
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();
  for (int n : c.tip) tip += (x - x0).segment<3>(3 * n);
  return tip / static_cast<double>(c.tip.size());
}

// Elastica of a cantilever under a dead tip load P (Mattiasson 1981): PL^2/EI = 1 gives
// u/L = 0.05643, w/L = 0.30172; PL^2/EI = 5 gives u/L = 0.38763, w/L = 0.71379. Beam 20 x 1 x 1,
// E = 1, nu = 0.3, quadratic tetrahedra, fully clamped. One rotation per element makes the
// co-rotational solution converge from the flexible side (measured w/L at PL^2/EI = 1: 0.3244
// on 20x1x1 cells, 0.3068 on 40x2x2, 0.3041 on 80x2x2); the test runs 40x2x2 and requires
// w within 2.5 % and u within 4.5 %, and that refinement from 20x1x1 reduces the error.
TEST(Elastica, LargeDeflectionCantilever) {
#ifdef __SANITIZE_ADDRESS__
  // 2.5 min under AddressSanitizer for the physics the test flavour checks; its code (the
  // co-rotational tetrahedra and the step solver) runs under the sanitizers in the patch,
  // bending and closure tests.
  GTEST_SKIP() << "the 40 x 2 x 2 beam's load steps take too long under AddressSanitizer";
#endif
  const double L = 20, h = 1, E = 1.0, nu = 0.3, I = h * h * h * h / 12;
  struct Case {
    double load, u, w;
    int steps;
  };
  auto solve = [&](const std::array<int, 3>& cells, const Case& k, int* iterations) {
    const Cantilever c = cantilever({L, h, h}, cells, TetOrder::kQuadratic);
    const auto end =
        boundary_faces(c.linear, [&](const auto& v) { return std::abs(v[0] - L) < 1e-9; });
    const double P = k.load * E * I / (L * L);
    const Eigen::VectorXd f = traction_load(c.solid, c.linear, end, {0, 0, -P / (h * h)});
    const Eigen::Vector3d tip =
        elastica_tip(c, TransverselyIsotropic::isotropic(E, nu), f, k.steps, iterations);
    return Eigen::Vector2d(-tip.x() / L, -tip.z() / L);
  };
  for (const Case& k : {Case{1.0, 0.05643, 0.30172, 5}, Case{5.0, 0.38763, 0.71379, 20}}) {
    int iterations = 0;
    const Eigen::Vector2d uw = solve({40, 2, 2}, k, &iterations);
    std::cout << "elastica PL^2/EI = " << k.load << ": u/L " << uw[0] << " (exact " << k.u
              << "), w/L " << uw[1] << " (exact " << k.w << "); 40x2x2 cells of quadratic tets, "
              << k.steps << " load steps, " << iterations << " Newton iterations\n";
    EXPECT_NEAR(uw[1], k.w, 0.025 * k.w);
    EXPECT_NEAR(uw[0], k.u, 0.045 * k.u);
    if (k.load == 1.0) {
      int it = 0;
      const Eigen::Vector2d coarse = solve({20, 1, 1}, k, &it);
      EXPECT_LT(std::abs(uw[1] - k.w), 0.5 * std::abs(coarse[1] - k.w));  // converging
    }
  }
}

}  // namespace
}  // namespace mvtwin::forward
