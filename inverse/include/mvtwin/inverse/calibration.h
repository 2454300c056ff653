#pragma once
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/calibration_file.h"
#include "mvtwin/inverse/closure_objective.h"

namespace mvtwin::inverse {

/// The optimizer of a calibration.
enum class FitMethod {
  kBobyqa,      ///< NLopt BOBYQA (derivative-free, quadratic models; the default)
  kCobyla,      ///< NLopt COBYLA (derivative-free, linear models)
  kNelderMead,  ///< NLopt Nelder-Mead simplex
  kSbplx,       ///< NLopt Sbplx (subspace simplex)
  kCeres,       ///< Ceres Levenberg-Marquardt: finite-difference Jacobian whose perturbed
                ///< simulations run in parallel, robust Huber loss
};
inline constexpr int kNumFitMethods = 5;
/// "bobyqa", "cobyla", "neldermead", "sbplx", "ceres".
const char* fit_method_name(FitMethod m);
/// The method named by fit_method_name(); nullopt for an unknown name.
std::optional<FitMethod> parse_fit_method(const std::string& name);
/// Every method by name (for the command line's choices).
std::map<std::string, FitMethod> fit_methods_by_name();

struct CalibrationOptions {
  FitMethod method = FitMethod::kBobyqa;
  int jobs = 2;  ///< simulations at once (TBB)
  /// Budget up to the fit: the start, the rest-length scan, then the optimizer (NLopt: its
  /// evaluations; Ceres: iterations x (n + 1)); 50 fits 7 parameters in about 45 s here.
  int max_simulations = 50;
  /// Stop when a step changes every parameter by less than this many of its scales.
  double step_tolerance = 0.05;
  /// Stop when the mean error improves by less than this, mm.
  double error_tolerance = 1e-4;
  /// Ceres: Huber loss width, mm (residuals beyond it count linearly).
  double huber_mm = 2.0;
  /// Ceres: forward-difference step in scales of each parameter.
  double fd_step = 0.25;
  /// Before the optimizer: when rest-length factors are fitted, simulate these common offsets
  /// of all of them from the start (in parallel) and start the optimizer from the best of
  /// them and the start. Local optimizers otherwise stall on valves far from the defaults,
  /// e.g. elongated chordae, trading the missing length for pressure. Empty: no scan.
  std::vector<double> restlength_scan = {-0.2, -0.1, 0.1, 0.2, 0.3, 0.4, 0.5};
  /// Observation noise SD for the covariance, mm; <= 0: the fit's residual RMS.
  double noise_mm = 0.0;
  /// Called after every improvement and every iteration.
  std::function<void(int iteration, double best_mm, int simulations)> progress;

  bool is_valid(std::string* error) const;
};

struct HistoryEntry {
  int simulation = 0;   ///< simulations run so far
  double error_mm = 0;  ///< this candidate's mean error (NaN when it failed)
  double best_mm = 0;   ///< best so far
  Eigen::VectorXd x;
};

struct CalibrationResult {
  std::string method, termination;
  std::vector<ParameterSpec> specs;
  /// `start`: the defaults; `optimizer_start`: where the optimizer began (after the scan).
  Eigen::VectorXd start, optimizer_start, fitted;
  /// Standard deviations and covariance (user units) from J^T J at the fit, scaled by the
  /// noise SD; correlation matrix. NaN where J^T J is singular.
  Eigen::VectorXd sd;
  Eigen::MatrixXd covariance, correlation;
  /// Whether the data determine each parameter: not along a null direction of J^T J and its
  /// sd at most its scale.
  std::vector<bool> identified;
  double noise_mm = 0;
  double error_before_mm = 0, error_after_mm = 0;
  int simulations = 0, failed_simulations = 0, cache_hits = 0;
  /// Failed candidate simulations by outcome (outcome_name -> count).
  std::map<std::string, int> failures_by_outcome;
  double wall_s = 0;
  std::vector<HistoryEntry> history;
  ValveParameters parameters;  ///< the fitted set (base plus fitted values)
};

/// Fits the objective's parameters. Failed candidate simulations are counted and penalized
/// (NLopt) or rejected (Ceres: the step is refused); they never end the fit. Throws
/// mvtwin::Error for invalid options or when the start point itself cannot be simulated.
CalibrationResult calibrate(ClosureObjective& objective, const CalibrationOptions& options = {});

/// Covariance of the fit from the Jacobian of the residuals (n columns, user units) and the
/// noise SD: sigma^2 (J^T J)^-1, pseudo-inverse on the well-determined subspace.
void fill_uncertainty(const Eigen::MatrixXd& J, double noise_mm, CalibrationResult* result);

/// The result as a file record (core/calibration_file.h): the fit, the simulation options, and,
/// for a virtual patient, the hidden values beside the fitted ones. Provenance is the caller's.
CalibrationRecord make_calibration_record(const CalibrationResult& result, const Patient& patient,
                                          const forward::ClosureOptions& simulation,
                                          const CalibrationOptions& options);

}  // namespace mvtwin::inverse
