#pragma once
#include <filesystem>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/patient.h"
#include "mvtwin/core/valve_parameters.h"

namespace mvtwin {

/// A per-patient calibration as stored on disk (docs/calibration-file.md): what was fitted,
/// how, the fitted values with their uncertainty, the error before and after, the history.
struct CalibrationRecord {
  std::string patient_id;
  std::string patient_file;
  bool synthetic = false;
  Provenance provenance;
  std::vector<std::pair<std::string, std::string>> options;  ///< simulation and fit options
  std::string method, termination;

  // Per fitted parameter (user units: mmHg for pressure).
  std::vector<std::string> names, units;
  Eigen::VectorXd lower, upper, start, fitted, sd;
  /// The virtual patient's hidden value (NaN for a real patient).
  Eigen::VectorXd truth;
  std::vector<int> identified;  ///< 1 where the data determine the parameter
  Eigen::MatrixXd covariance, correlation;
  double noise_mm = 0;  ///< the noise SD the covariance is scaled by

  ValveParameters parameters;  ///< the full fitted set (unfitted ones at their defaults)
  double error_before_mm = 0, error_after_mm = 0;
  int simulations = 0, failed_simulations = 0, cache_hits = 0;
  double wall_s = 0;
  /// With a search model (a cheaper model the optimizer ran on; the `fit_search_*` options say
  /// which): its share of the simulations, its errors at the start and at its fit, and what the
  /// refinement on the fit's model did. Without one: 0, NaN, NaN, empty. Files written before
  /// search models existed read as without one.
  int search_simulations = 0;
  double search_error_before_mm = std::numeric_limits<double>::quiet_NaN();
  double search_error_after_mm = std::numeric_limits<double>::quiet_NaN();
  std::string refinement;

  // Convergence history, one row per simulation run.
  std::vector<int> history_simulation;
  std::vector<double> history_error_mm, history_best_mm;
  Eigen::MatrixXd history_x;  ///< (H, n)
};

/// Writes atomically. Throws mvtwin::Error for inconsistent sizes or an unwritable path.
void write_calibration_file(const std::filesystem::path& path, const CalibrationRecord& r);
/// Throws mvtwin::Error naming the problem (not a calibration file, missing data, ...).
CalibrationRecord read_calibration_file(const std::filesystem::path& path);

}  // namespace mvtwin
