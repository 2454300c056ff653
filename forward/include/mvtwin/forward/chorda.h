#pragma once
#include <Eigen/Core>

namespace mvtwin::forward {

/// A chorda tendinea as a tension-only cable with a continuous bilinear stress-strain law
/// (Mansi et al. 2012, Sec. 2.3: the paper's strain-dependent stiffness times the whole elongation
/// jumps at the breakpoint; the measured curve it approximates is continuous).
///   sigma(eps) = 0                                     eps <= 0   (no force in compression)
///              = E_low eps                             0 < eps <= eps_break
///              = E_low eps_break + E_high (eps - eps_break)   eps > eps_break
/// with eps = (l - L0) / L0 the engineering strain. Force T = A0 sigma.
struct ChordaLaw {
  double area = 0.0;          ///< A0, mm^2
  double e_low = 0.0;         ///< MPa
  double e_high = 0.0;        ///< MPa
  double strain_break = 0.0;  ///< dimensionless

  /// Marginal chordae: A0 0.40 mm^2, E 312 / 3406 gf/mm^2, break at 2.5 % (Mansi 2012, Table 1).
  static ChordaLaw marginal();
  /// Basal chordae: A0 2.05 mm^2, E 66 / 2120 gf/mm^2, break at 5 %.
  static ChordaLaw basal();
  ChordaLaw stiffness_scaled(double s) const { return {area, e_low * s, e_high * s, strain_break}; }

  double stress(double strain) const;          ///< MPa
  double tangent(double strain) const;         ///< d stress / d strain, MPa
  double energy_density(double strain) const;  ///< integral of stress, MPa
};

/// Gradient (minus the force) and tangent of a chorda between points a and b with rest length
/// L0 (mm). g = (g_a, g_b), H the 6x6 Hessian (exact; symmetric). Energy in N mm.
void chorda_gradient(const ChordaLaw& law, double rest_length, const Eigen::Vector3d& a,
                     const Eigen::Vector3d& b, Eigen::Matrix<double, 6, 1>* g,
                     Eigen::Matrix<double, 6, 6>* H, double* energy = nullptr);

/// A two-way linear spring between points a and b (a clip device's tie): force k (l - L0) along
/// b - a, pulling when stretched and pushing when compressed, energy k (l - L0)^2 / 2; the same
/// layout as chorda_gradient. H is the Gauss-Newton tangent k n n^T plus the geometric term
/// (T / l)(I - n n^T) only while the tie pulls (T > 0), so that it stays positive semidefinite.
void tie_gradient(double k, double rest_length, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                  Eigen::Matrix<double, 6, 1>* g, Eigen::Matrix<double, 6, 6>* H,
                  double* energy = nullptr);

}  // namespace mvtwin::forward
