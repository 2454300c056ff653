#include "mvtwin/forward/transversely_isotropic.h"

#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

namespace mvtwin::forward {
namespace {

Eigen::Matrix3d voigt_to_tensor(const Eigen::Matrix<double, 6, 1>& e) {
  Eigen::Matrix3d t;
  t << e[0], 0.5 * e[5], 0.5 * e[4], 0.5 * e[5], e[1], 0.5 * e[3], 0.5 * e[4], 0.5 * e[3], e[2];
  return t;
}

Eigen::Matrix<double, 6, 1> tensor_to_voigt(const Eigen::Matrix3d& t) {
  Eigen::Matrix<double, 6, 1> e;
  e << t(0, 0), t(1, 1), t(2, 2), 2.0 * t(1, 2), 2.0 * t(0, 2), 2.0 * t(0, 1);
  return e;
}

}  // namespace

// Mansi et al. 2012, Table 1 (after Votta et al. 2008): E_fibre, E_cross, G in MPa; nu = 0.488.
TransverselyIsotropic TransverselyIsotropic::anterior_leaflet() {
  return {6.233, 2.350, 1.369, 0.488, 0.488};
}
TransverselyIsotropic TransverselyIsotropic::posterior_leaflet() {
  return {2.087, 1.887, 0.694, 0.488, 0.488};
}
TransverselyIsotropic TransverselyIsotropic::isotropic(double e, double nu) {
  return {e, e, e / (2.0 * (1.0 + nu)), nu, nu};
}

TransverselyIsotropic TransverselyIsotropic::scaled(double s) const {
  return {e_fibre * s, e_cross * s, g_fibre * s, nu_fibre, nu_cross};
}

bool TransverselyIsotropic::is_valid(std::string* error) const {
  if (!(e_fibre > 0 && e_cross > 0 && g_fibre > 0)) {
    *error = "moduli must be positive (E_fibre " + std::to_string(e_fibre) + ", E_cross " +
             std::to_string(e_cross) + ", G " + std::to_string(g_fibre) + " MPa)";
    return false;
  }
  if (!(nu_cross > -1.0 && nu_cross < 1.0)) {
    *error = "nu23 must lie in (-1, 1)";
    return false;
  }
  if (compliance_local().llt().info() != Eigen::Success) {
    *error = "compliance is not positive definite (Poisson ratios too large for these moduli)";
    return false;
  }
  return true;
}

Eigen::Matrix<double, 6, 6> TransverselyIsotropic::compliance_local() const {
  Eigen::Matrix<double, 6, 6> S = Eigen::Matrix<double, 6, 6>::Zero();
  S(0, 0) = 1.0 / e_fibre;
  S(1, 1) = S(2, 2) = 1.0 / e_cross;
  S(0, 1) = S(1, 0) = S(0, 2) = S(2, 0) = -nu_fibre / e_fibre;
  S(1, 2) = S(2, 1) = -nu_cross / e_cross;
  S(3, 3) = 1.0 / g_cross();
  S(4, 4) = S(5, 5) = 1.0 / g_fibre;
  return S;
}

Eigen::Matrix<double, 6, 6> TransverselyIsotropic::stiffness_local() const {
  return compliance_local().inverse();
}

Eigen::Matrix<double, 6, 6> strain_rotation(const Eigen::Matrix3d& Q) {
  Eigen::Matrix<double, 6, 6> T;
  for (int k = 0; k < 6; ++k) {
    const Eigen::Matrix<double, 6, 1> e = Eigen::Matrix<double, 6, 1>::Unit(k);
    T.col(k) = tensor_to_voigt(Q * voigt_to_tensor(e) * Q.transpose());
  }
  return T;
}

Eigen::Matrix<double, 6, 6> TransverselyIsotropic::stiffness(const Eigen::Vector3d& fibre) const {
  const Eigen::Vector3d a = fibre.normalized();
  const Eigen::Vector3d helper =
      std::abs(a.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d b = a.cross(helper).normalized();
  const Eigen::Vector3d c = a.cross(b);
  Eigen::Matrix3d Q;
  Q.row(0) = a.transpose();
  Q.row(1) = b.transpose();
  Q.row(2) = c.transpose();
  const Eigen::Matrix<double, 6, 6> T = strain_rotation(Q);
  return T.transpose() * stiffness_local() * T;
}

}  // namespace mvtwin::forward
