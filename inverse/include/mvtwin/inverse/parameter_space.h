#pragma once
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/valve_parameters.h"

namespace mvtwin::inverse {

/// One parameter a calibration can fit: a member of ValveParameters as the user sees it.
/// Values in `unit` (the user's: mmHg for pressure); `to_internal` converts to the member's
/// unit. `scale` is the typical size of a change, used to normalize the optimizers' variables
/// (z = (value - default) / scale) and their finite-difference steps.
struct ParameterSpec {
  std::string name;   ///< as in ValveParameters::for_each ("restlength_factor_...", ...)
  std::string group;  ///< restlength | stiffness | pressure | modulus
  std::string unit;
  double lower = 0, upper = 0, default_value = 0, scale = 1;
  double to_internal = 1.0;
};

/// Every parameter mvtwin can fit, in a fixed order: the 4 chordae rest-length factors, the
/// marginal and basal stiffness scales, the peak pressure, the AL and PL modulus scales.
const std::vector<ParameterSpec>& parameter_catalogue();

/// The parameters chosen for a fit, over a base ValveParameters that holds the others.
class ParameterSpace {
 public:
  /// `selection`: comma-separated groups (restlength, stiffness, pressure, modulus) and/or
  /// parameter names, e.g. "restlength,stiffness,pressure". Throws mvtwin::Error naming an
  /// unknown entry or an empty selection. The start point is `base`'s values (clamped to the
  /// bounds).
  ParameterSpace(const std::string& selection, const ValveParameters& base);

  int size() const { return static_cast<int>(specs_.size()); }
  const std::vector<ParameterSpec>& specs() const { return specs_; }
  const ValveParameters& base() const { return base_; }

  /// Values of the chosen parameters in `p`, user units.
  Eigen::VectorXd values_of(const ValveParameters& p) const;
  /// `base` with the chosen parameters set to `x` (user units). Throws mvtwin::Error for a
  /// non-finite value or one outside the bounds by more than a rounding error.
  ValveParameters apply(const Eigen::VectorXd& x) const;
  Eigen::VectorXd lower() const;
  Eigen::VectorXd upper() const;
  Eigen::VectorXd scales() const;
  /// The start point: base's values clamped into the bounds.
  Eigen::VectorXd start() const;
  /// Comma-separated names of the chosen parameters.
  std::string names() const;

 private:
  std::vector<ParameterSpec> specs_;
  ValveParameters base_;
};

}  // namespace mvtwin::inverse
