#include "mvtwin/forward/elastic_body.h"

#include "run_both.h"

#include <cmath>
#include <string>

#include <Eigen/LU>

#include "mvtwin/core/error.h"

namespace mvtwin::forward {

ElasticBody::ElasticBody(SolidMesh mesh,
                         const std::function<TransverselyIsotropic(int tag)>& material)
    : mesh_(std::move(mesh)) {
  const int n = mesh_.nodes_per_element();
  for (int e = 0; e < mesh_.num_elements(); ++e) {
    const TransverselyIsotropic m = material(mesh_.tag[e]);
    std::string err;
    if (!m.is_valid(&err)) throw Error("element " + std::to_string(e) + " material: " + err);
    const Eigen::Matrix<double, 6, 6> C = m.stiffness(mesh_.fibre.row(e).transpose());
    const double kappa = (C(0, 0) + C(1, 1) + C(2, 2)) / 3.0;
    auto rest = [&](auto& X) {
      for (int a = 0; a < n; ++a) X.row(a) = mesh_.V.row(mesh_.T(e, a));
      Eigen::Matrix3d Dm;
      for (int j = 0; j < 3; ++j) Dm.col(j) = (X.row(j + 1) - X.row(0)).transpose();
      if (!(Dm.determinant() > 0))
        throw Error("element " + std::to_string(e) + " is inverted or flat at rest");
    };
    if (n == 4) {
      CorotationalTet<4>::Nodes X;
      rest(X);
      linear_.emplace_back(X, C);
      guard_scale_.push_back(kappa * linear_.back().rest_volume());
    } else {
      CorotationalTet<10>::Nodes X;
      rest(X);
      quadratic_.emplace_back(X, C);
      if (!(quadratic_.back().min_jacobian() > 0.0)) {
        throw Error("element " + std::to_string(e) +
                    " is inverted inside (its mid-edge nodes fold it) at rest");
      }
      guard_scale_.push_back(kappa * quadratic_.back().rest_volume());
    }
  }
}

Eigen::VectorXd ElasticBody::rest_positions() const {
  Eigen::VectorXd x(num_dofs());
  for (int i = 0; i < mesh_.num_nodes(); ++i) x.segment<3>(3 * i) = mesh_.V.row(i).transpose();
  return x;
}

Eigen::VectorXd ElasticBody::lumped_mass(double density) const {
  Eigen::VectorXd m = Eigen::VectorXd::Zero(mesh_.num_nodes());
  const int n = mesh_.nodes_per_element();
  for (int e = 0; e < mesh_.num_elements(); ++e) {
    const double vol = n == 4 ? linear_[e].rest_volume() : quadratic_[e].rest_volume();
    for (int a = 0; a < n; ++a) {
      const double f = n == 4 ? CorotationalTet<4>::mass_fractions()[a]
                              : CorotationalTet<10>::mass_fractions()[a];
      m[mesh_.T(e, a)] += density * vol * f;
    }
  }
  return m;
}

template <int N>
int ElasticBody::accumulate_order(const std::vector<CorotationalTet<N>>& elems,
                                  const Eigen::VectorXd& x, Eigen::VectorXd* g,
                                  std::vector<Eigen::Triplet<double>>* H, Tangent tangent,
                                  double* energy) const {
  using Tet = CorotationalTet<N>;
  typename Tet::Nodes xe;
  typename Tet::Vector ge;
  typename Tet::Matrix He;
  for (int e = 0; e < static_cast<int>(elems.size()); ++e) {
    for (int a = 0; a < N; ++a) xe.row(a) = x.segment<3>(3 * mesh_.T(e, a)).transpose();
    double en = 0.0;
    const bool ok = elems[e].evaluate(xe, g ? &ge : nullptr,
                                      H && tangent == Tangent::kConsistent ? &He : nullptr,
                                      H && tangent == Tangent::kWarped ? &He : nullptr, &en);
    if (!ok) return e;
    if (energy) *energy += en;
    for (int a = 0; a < N; ++a) {
      const int ia = mesh_.T(e, a);
      if (g) g->segment<3>(3 * ia) += ge.template segment<3>(3 * a);
      if (!H) continue;
      for (int b = 0; b < N; ++b) {
        const int ib = mesh_.T(e, b);
        for (int r = 0; r < 3; ++r) {
          for (int c = 0; c < 3; ++c)
            H->emplace_back(3 * ia + r, 3 * ib + c, He(3 * a + r, 3 * b + c));
        }
      }
    }
  }
  return -1;
}

int ElasticBody::accumulate(const Eigen::VectorXd& x, Eigen::VectorXd* g,
                            std::vector<Eigen::Triplet<double>>* H, Tangent tangent,
                            double* energy) const {
  if (mesh_.order == TetOrder::kLinear) return accumulate_order(linear_, x, g, H, tangent, energy);
  return accumulate_order(quadratic_, x, g, H, tangent, energy);
}

template <int N>
int ElasticBody::gradient_range(const std::vector<CorotationalTet<N>>& elems, int e0, int e1,
                                const Eigen::VectorXd& x, Eigen::VectorXd* g, ElementRotations* rot,
                                std::vector<ElementRotations::Guard>* guards, double* energy,
                                const Eigen::VectorXd* p, Eigen::VectorXd* Kp) const {
  using Tet = CorotationalTet<N>;
  typename Tet::Nodes xe;
  typename Tet::Vector ge, pe, kpe;
  g->setZero(x.size());
  if (p) Kp->setZero(x.size());
  if (energy) *energy = 0.0;
  Eigen::Matrix<double, 12, 1> dJ;
  for (int e = e0; e < e1; ++e) {
    for (int a = 0; a < N; ++a) xe.row(a) = x.segment<3>(3 * mesh_.T(e, a)).transpose();
    if (!elems[e].rotation(xe, &rot->R[e])) return e;
    double en = 0.0;
    if (p) {
      for (int a = 0; a < N; ++a) pe.template segment<3>(3 * a) = p->segment<3>(3 * mesh_.T(e, a));
      elems[e].gradient(rot->R[e], xe, &ge, energy ? &en : nullptr, &pe, &kpe);
    } else {
      elems[e].gradient(rot->R[e], xe, &ge, energy ? &en : nullptr);
    }
    if (guard_j0_ > 0.0) {
      const double J = elems[e].corner_jacobian(xe, &dJ);
      if (J < guard_j0_) {
        // phi = -(J - j0)^2 ln(J / j0) and its first two derivatives (all >= 0 below j0).
        const double j0 = guard_j0_, lg = std::log(J / j0), d = J - j0;
        const double phi = -d * d * lg;
        const double phi1 = -2.0 * d * lg - d * d / J;
        const double phi2 = -2.0 * lg - 4.0 * d / J + d * d / (J * J);
        const double k = guard_scale_[e];
        ge.template head<12>() += k * phi1 * dJ;
        en += k * phi;
        guards->push_back({e, k * phi2, dJ});
        if (p) kpe.template head<12>() += k * phi2 * dJ.dot(pe.template head<12>()) * dJ;
      }
    }
    if (p) {
      for (int a = 0; a < N; ++a)
        Kp->segment<3>(3 * mesh_.T(e, a)) += kpe.template segment<3>(3 * a);
    }
    if (energy) *energy += en;
    for (int a = 0; a < N; ++a) g->segment<3>(3 * mesh_.T(e, a)) += ge.template segment<3>(3 * a);
  }
  return -1;
}

// Two halves of the elements (run_both): the first half accumulates into the outputs, the
// second into its own vectors, added after; the same sums in the same order on 1 or 2 threads.
template <int N>
int ElasticBody::gradient_order(const std::vector<CorotationalTet<N>>& elems,
                                const Eigen::VectorXd& x, Eigen::VectorXd* g, ElementRotations* rot,
                                double* energy, const Eigen::VectorXd* p,
                                Eigen::VectorXd* Kp) const {
  const int E = static_cast<int>(elems.size()), half = E / 2;
  rot->R.resize(E);
  rot->guards.clear();
  rot->guard_of_element.assign(E, -1);
  Eigen::VectorXd g1, Kp1;
  std::vector<ElementRotations::Guard> guards1;
  double energy0 = 0.0, energy1 = 0.0;
  int bad0 = -1, bad1 = -1;
  run_both(
      threads_,
      [&] {
        bad0 = gradient_range(elems, 0, half, x, g, rot, &rot->guards, energy ? &energy0 : nullptr,
                              p, Kp);
      },
      [&] {
        bad1 = gradient_range(elems, half, E, x, &g1, rot, &guards1, energy ? &energy1 : nullptr, p,
                              &Kp1);
      });
  if (bad0 >= 0) return bad0;
  if (bad1 >= 0) return bad1;
  *g += g1;
  if (p) *Kp += Kp1;
  if (energy) *energy = energy0 + energy1;
  rot->guards.insert(rot->guards.end(), guards1.begin(), guards1.end());
  for (size_t i = 0; i < rot->guards.size(); ++i)
    rot->guard_of_element[rot->guards[i].element] = static_cast<int>(i);
  return -1;
}

template <int N>
void ElasticBody::tangent_times_range(const std::vector<CorotationalTet<N>>& elems, int e0, int e1,
                                      const ElementRotations& rot, const Eigen::VectorXd& p,
                                      Eigen::VectorXd* y) const {
  using Tet = CorotationalTet<N>;
  typename Tet::Vector pe;
  for (int e = e0; e < e1; ++e) {
    for (int a = 0; a < N; ++a) pe.template segment<3>(3 * a) = p.segment<3>(3 * mesh_.T(e, a));
    typename Tet::Vector ye = elems[e].tangent_times(rot.R[e], pe);
    if (!rot.guard_of_element.empty() && rot.guard_of_element[e] >= 0) {
      const auto& gd = rot.guards[rot.guard_of_element[e]];
      ye.template head<12>() += gd.coefficient * gd.dJ.dot(pe.template head<12>()) * gd.dJ;
    }
    for (int a = 0; a < N; ++a) y->segment<3>(3 * mesh_.T(e, a)) += ye.template segment<3>(3 * a);
  }
}

template <int N>
void ElasticBody::tangent_times_order(const std::vector<CorotationalTet<N>>& elems,
                                      const ElementRotations& rot, const Eigen::VectorXd& p,
                                      Eigen::VectorXd* y) const {
  const int E = static_cast<int>(elems.size()), half = E / 2;
  Eigen::VectorXd y1 = Eigen::VectorXd::Zero(y->size());
  run_both(
      threads_, [&] { tangent_times_range(elems, 0, half, rot, p, y); },
      [&] { tangent_times_range(elems, half, E, rot, p, &y1); });
  *y += y1;
}

template <int N>
void ElasticBody::assemble_order(const std::vector<CorotationalTet<N>>& elems,
                                 const ElementRotations& rot, double s,
                                 SymmetricBlockMatrix* A) const {
  typename CorotationalTet<N>::Matrix K;
  for (int e = 0; e < static_cast<int>(elems.size()); ++e) {
    elems[e].warped_tangent(rot.R[e], &K);
    if (!rot.guard_of_element.empty() && rot.guard_of_element[e] >= 0) {
      const auto& gd = rot.guards[rot.guard_of_element[e]];
      K.template topLeftCorner<12, 12>() += gd.coefficient * gd.dJ * gd.dJ.transpose();
    }
    A->add_clique(e, K, s);
  }
}

template <int N>
int ElasticBody::consistent_order(const std::vector<CorotationalTet<N>>& elems,
                                  const Eigen::VectorXd& x, const ElementRotations& rot,
                                  std::vector<Eigen::MatrixXd>* K) const {
  typename CorotationalTet<N>::Nodes xe;
  typename CorotationalTet<N>::Matrix Ke;
  K->resize(elems.size());
  for (int e = 0; e < static_cast<int>(elems.size()); ++e) {
    for (int a = 0; a < N; ++a) xe.row(a) = x.segment<3>(3 * mesh_.T(e, a)).transpose();
    if (!elems[e].evaluate(xe, nullptr, &Ke, nullptr)) return e;
    if (guard_j0_ > 0.0 && !rot.guard_of_element.empty() && rot.guard_of_element[e] >= 0) {
      // The guard's whole Hessian: k (phi'' dJ dJ^T + phi' d2J), d2J by central differences of
      // the exact dJ (det F is cubic in the corners: the difference is exact up to round-off).
      Eigen::Matrix<double, 12, 1> dJ, dp, dm;
      const double J = elems[e].corner_jacobian(xe, &dJ);
      const double j0 = guard_j0_, lg = std::log(J / j0), d = J - j0;
      const double phi1 = -2.0 * d * lg - d * d / J;
      const double phi2 = -2.0 * lg - 4.0 * d / J + d * d / (J * J);
      Eigen::Matrix<double, 12, 12> d2J;
      const double h = 1e-6 * std::max(1.0, xe.template topRows<4>().cwiseAbs().maxCoeff());
      for (int j = 0; j < 12; ++j) {
        typename CorotationalTet<N>::Nodes xp = xe, xm = xe;
        xp(j / 3, j % 3) += h;
        xm(j / 3, j % 3) -= h;
        elems[e].corner_jacobian(xp, &dp);
        elems[e].corner_jacobian(xm, &dm);
        d2J.col(j) = (dp - dm) / (2 * h);
      }
      const double k = guard_scale_[e];
      Ke.template topLeftCorner<12, 12>() +=
          k * (phi2 * dJ * dJ.transpose() + phi1 * 0.5 * (d2J + d2J.transpose()));
    }
    (*K)[e] = Ke;
  }
  return -1;
}

int ElasticBody::consistent_tangents(const Eigen::VectorXd& x, const ElementRotations& rot,
                                     std::vector<Eigen::MatrixXd>* K) const {
  if (mesh_.order == TetOrder::kLinear) return consistent_order(linear_, x, rot, K);
  return consistent_order(quadratic_, x, rot, K);
}

namespace {
template <int N>
void element_products(const SolidMesh& mesh, const std::vector<Eigen::MatrixXd>& K,
                      const Eigen::VectorXd& p, Eigen::VectorXd* y) {
  using Matrix = Eigen::Matrix<double, 3 * N, 3 * N>;
  Eigen::Matrix<double, 3 * N, 1> pe, ye;
  for (int e = 0; e < static_cast<int>(K.size()); ++e) {
    for (int a = 0; a < N; ++a) pe.template segment<3>(3 * a) = p.segment<3>(3 * mesh.T(e, a));
    ye.noalias() = Eigen::Map<const Matrix>(K[e].data()) * pe;
    for (int a = 0; a < N; ++a) y->segment<3>(3 * mesh.T(e, a)) += ye.template segment<3>(3 * a);
  }
}
}  // namespace

void ElasticBody::tangents_times(const std::vector<Eigen::MatrixXd>& K, const Eigen::VectorXd& p,
                                 Eigen::VectorXd* y) const {
  if (mesh_.order == TetOrder::kLinear) return element_products<4>(mesh_, K, p, y);
  element_products<10>(mesh_, K, p, y);
}

int ElasticBody::gradient(const Eigen::VectorXd& x, Eigen::VectorXd* g, ElementRotations* rot,
                          double* energy, const Eigen::VectorXd* p, Eigen::VectorXd* Kp) const {
  if (mesh_.order == TetOrder::kLinear) return gradient_order(linear_, x, g, rot, energy, p, Kp);
  return gradient_order(quadratic_, x, g, rot, energy, p, Kp);
}

void ElasticBody::tangent_times(const ElementRotations& rot, const Eigen::VectorXd& p,
                                Eigen::VectorXd* y) const {
  if (mesh_.order == TetOrder::kLinear) return tangent_times_order(linear_, rot, p, y);
  tangent_times_order(quadratic_, rot, p, y);
}

void ElasticBody::assemble_tangent(const ElementRotations& rot, double s,
                                   SymmetricBlockMatrix* A) const {
  if (mesh_.order == TetOrder::kLinear) return assemble_order(linear_, rot, s, A);
  assemble_order(quadratic_, rot, s, A);
}

int ElasticBody::first_inverted(const Eigen::VectorXd& x) const {
  for (int e = 0; e < mesh_.num_elements(); ++e) {
    Eigen::Matrix3d Ds, Dm;
    for (int j = 0; j < 3; ++j) {
      Ds.col(j) = x.segment<3>(3 * mesh_.T(e, j + 1)) - x.segment<3>(3 * mesh_.T(e, 0));
      Dm.col(j) = (mesh_.V.row(mesh_.T(e, j + 1)) - mesh_.V.row(mesh_.T(e, 0))).transpose();
    }
    // Rest elements have det Dm > 0 (checked at construction).
    if (!(Ds.determinant() > 0.0)) return e;
  }
  return -1;
}

std::vector<std::vector<int>> ElasticBody::element_cliques() const {
  std::vector<std::vector<int>> c(mesh_.num_elements());
  const int n = mesh_.nodes_per_element();
  for (int e = 0; e < mesh_.num_elements(); ++e) {
    for (int a = 0; a < n; ++a) c[e].push_back(mesh_.T(e, a));
  }
  return c;
}

}  // namespace mvtwin::forward
