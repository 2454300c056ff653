#include "mvtwin/forward/chorda.h"

#include <algorithm>

#include "mvtwin/core/units.h"

namespace mvtwin::forward {

ChordaLaw ChordaLaw::marginal() {
  return {0.40, units::gf_per_mm2_to_mpa(312.0), units::gf_per_mm2_to_mpa(3406.0), 0.025};
}
ChordaLaw ChordaLaw::basal() {
  return {2.05, units::gf_per_mm2_to_mpa(66.0), units::gf_per_mm2_to_mpa(2120.0), 0.05};
}

double ChordaLaw::stress(double e) const {
  if (e <= 0.0) return 0.0;
  if (e <= strain_break) return e_low * e;
  return e_low * strain_break + e_high * (e - strain_break);
}

double ChordaLaw::tangent(double e) const {
  if (e <= 0.0) return 0.0;
  return e <= strain_break ? e_low : e_high;
}

double ChordaLaw::energy_density(double e) const {
  if (e <= 0.0) return 0.0;
  if (e <= strain_break) return 0.5 * e_low * e * e;
  const double d = e - strain_break;
  return 0.5 * e_low * strain_break * strain_break + e_low * strain_break * d +
         0.5 * e_high * d * d;
}

void chorda_gradient(const ChordaLaw& law, double L0, const Eigen::Vector3d& a,
                     const Eigen::Vector3d& b, Eigen::Matrix<double, 6, 1>* g,
                     Eigen::Matrix<double, 6, 6>* H, double* energy) {
  const Eigen::Vector3d d = b - a;
  const double l = d.norm();
  const double strain = (l - L0) / L0;
  if (energy) *energy = law.area * L0 * law.energy_density(strain);
  const double T = law.area * law.stress(strain);  // N
  if (g) g->setZero();
  if (H) H->setZero();
  if (T <= 0.0 || l <= 0.0) return;  // slack: no force, no stiffness
  const Eigen::Vector3d n = d / l;
  if (g) {
    g->head<3>() = -T * n;
    g->tail<3>() = T * n;
  }
  if (H) {
    const double dTdl = law.area * law.tangent(strain) / L0;
    const Eigen::Matrix3d Kb =
        dTdl * n * n.transpose() + (T / l) * (Eigen::Matrix3d::Identity() - n * n.transpose());
    H->topLeftCorner<3, 3>() = Kb;
    H->bottomRightCorner<3, 3>() = Kb;
    H->topRightCorner<3, 3>() = -Kb;
    H->bottomLeftCorner<3, 3>() = -Kb;
  }
}

void tie_gradient(double k, double L0, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                  Eigen::Matrix<double, 6, 1>* g, Eigen::Matrix<double, 6, 6>* H, double* energy) {
  const Eigen::Vector3d d = b - a;
  const double l = d.norm();
  const double T = k * (l - L0);  // N, negative when pushing
  if (energy) *energy = 0.5 * k * (l - L0) * (l - L0);
  if (g) g->setZero();
  if (H) H->setZero();
  if (l <= 0.0) return;
  const Eigen::Vector3d n = d / l;
  if (g) {
    g->head<3>() = -T * n;
    g->tail<3>() = T * n;
  }
  if (H) {
    const Eigen::Matrix3d P = n * n.transpose();
    const Eigen::Matrix3d Kb = k * P + (std::max(T, 0.0) / l) * (Eigen::Matrix3d::Identity() - P);
    H->topLeftCorner<3, 3>() = Kb;
    H->bottomRightCorner<3, 3>() = Kb;
    H->topRightCorner<3, 3>() = -Kb;
    H->bottomLeftCorner<3, 3>() = -Kb;
  }
}

}  // namespace mvtwin::forward
