#pragma once
#include <functional>
#include <limits>
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
  /// Budget up to the fit: the start, the scans, then the optimizer (NLopt: its
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
  /// When the leaflets' moduli are fitted: these common multipliers of both modulus scales from
  /// the start, simulated in the same batch as the rest-length scan, then the best point of each
  /// line combined (one more simulation); the optimizer starts from the best of all. Stiff
  /// leaflets otherwise look like short chordae from the start: on the clip study's stiff
  /// patient 4 the fit stopped at 0.82 mm (anterolateral marginal factor 0.77, moduli 0.64 /
  /// 1.55) where the truth's parameters leave 0.34 (truth 1.01, moduli 2.04 / 2.87); a budget
  /// of 150 instead of 50 converged to the same point (docs/calibration.md). Must be > 0.
  /// Empty: no modulus scan.
  std::vector<double> modulus_scan = {0.5, 1.5, 2.0, 3.0, 4.0};
  /// Observation noise SD for the covariance, mm; <= 0: the fit's residual RMS.
  double noise_mm = 0.0;
  /// A cheaper model to search with (the start, the scan and the optimizer run on it), for
  /// example the objective's model at 24 x 24 (search_model_for()). The fit is then finished
  /// on the objective's own model: the start and the search's fit are simulated there with
  /// the uncertainty's Jacobian, and one damped Gauss-Newton step from that Jacobian (two
  /// dampings, at once) is kept when it lowers the error. Empty, or the objective's model
  /// itself: the whole fit runs on the objective's model.
  std::optional<forward::ClosureOptions> search_model;
  /// Called after every improvement and every iteration (the simulations counted over both
  /// models, the best error on the model the stage runs on).
  std::function<void(int iteration, double best_mm, int simulations)> progress;
  /// Called when a stage begins: "search on the 24 x 24 model", "refine on the 30 x 30 model".
  std::function<void(const std::string& stage)> stage;

  bool is_valid(std::string* error) const;
};

/// The default search model for calibrating with `model`: the same model at 0.8 of its grid in
/// each direction (24 x 24 for the paper's 30 x 30: a closure costs about 0.6 of one there),
/// settling for at most 1 s, when it has at least 25 points around the annulus, else none (the
/// fit searches on `model`).
std::optional<forward::ClosureOptions> search_model_for(const forward::ClosureOptions& model);

/// The refinement's candidates: damped Gauss-Newton steps from x, for the distances r and their
/// Jacobian J (user units), one per damping: (A + lambda diag A) dz = -J_z^T r with A = J_z^T
/// J_z in scales of each parameter (J_z = J diag(scale)), each step shortened to at most one
/// scale per parameter and clamped to the bounds. The distances are unsigned, so a step only
/// proposes: the caller keeps it if the simulated error falls. Empty when J is zero.
std::vector<Eigen::VectorXd> gauss_newton_steps(const ParameterSpace& space,
                                                const Eigen::VectorXd& x, const Eigen::VectorXd& r,
                                                const Eigen::MatrixXd& J,
                                                const std::vector<double>& dampings);

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
  /// Simulations of all of it; failed ones and cache hits over both models.
  int simulations = 0, failed_simulations = 0, cache_hits = 0;
  /// With a search model: its simulations, its errors at the start and at its fit, where its
  /// fit was (`search_fitted`, which the refinement starts from), and what the refinement did.
  /// Without one: 0, NaN, empty.
  int search_simulations = 0;
  double search_error_before_mm = std::numeric_limits<double>::quiet_NaN();
  double search_error_after_mm = std::numeric_limits<double>::quiet_NaN();
  Eigen::VectorXd search_fitted;
  std::string refinement;
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
