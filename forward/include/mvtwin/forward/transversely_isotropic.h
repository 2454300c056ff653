#pragma once
#include <string>

#include <Eigen/Core>

namespace mvtwin::forward {

/// Linear transversely isotropic elasticity: fibre axis 1, isotropic plane 2-3 (Mansi et al. 2012,
/// Sec. 2.3). Five constants: E1 = E_fibre, E2 = E3 = E_cross, nu12 = nu13, nu23, G12 = G13; and
/// G23 = E2 / (2 (1 + nu23)). Moduli in MPa.
struct TransverselyIsotropic {
  double e_fibre = 0.0;   ///< E1, MPa
  double e_cross = 0.0;   ///< E2 = E3, MPa
  double g_fibre = 0.0;   ///< G12 = G13, MPa
  double nu_fibre = 0.0;  ///< nu12 = nu13
  double nu_cross = 0.0;  ///< nu23

  /// The paper's anterior / posterior leaflet (Mansi et al. 2012, Table 1), nu = 0.488.
  static TransverselyIsotropic anterior_leaflet();
  static TransverselyIsotropic posterior_leaflet();
  /// An isotropic material as the special case E1 = E2, G = E/(2(1+nu)).
  static TransverselyIsotropic isotropic(double e, double nu);

  /// All moduli multiplied by s (Poisson ratios unchanged).
  TransverselyIsotropic scaled(double s) const;

  double g_cross() const { return e_cross / (2.0 * (1.0 + nu_cross)); }

  /// False with a reason when the constants are not physical (non-positive moduli or a
  /// compliance that is not positive definite).
  bool is_valid(std::string* error) const;

  /// 6x6 compliance and stiffness in the material frame, Voigt order (11, 22, 33, 23, 13, 12)
  /// with engineering shear strains (gamma = 2 eps).
  Eigen::Matrix<double, 6, 6> compliance_local() const;
  Eigen::Matrix<double, 6, 6> stiffness_local() const;
  /// Stiffness in the global frame for a unit fibre direction (any orthonormal completion of the
  /// 2-3 plane gives the same result, by transverse isotropy).
  Eigen::Matrix<double, 6, 6> stiffness(const Eigen::Vector3d& fibre) const;
};

/// Voigt (engineering) strain transformation T with eps_local = T eps_global for the rotation
/// Q whose rows are the local axes in global coordinates.
Eigen::Matrix<double, 6, 6> strain_rotation(const Eigen::Matrix3d& Q);

}  // namespace mvtwin::forward
