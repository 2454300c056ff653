#pragma once
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/outcome.h"
#include "mvtwin/core/patient.h"
#include "mvtwin/core/triangle_mesh.h"
#include "mvtwin/forward/closure_simulation.h"
#include "mvtwin/inverse/parameter_space.h"

namespace mvtwin::inverse {

/// What a candidate's simulated closure is compared with.
struct ObjectiveOptions {
  /// The calibration model (never the one that made a virtual patient's observation).
  forward::ClosureOptions simulation;
  /// Compare every observed frame after end-diastole up to the first closed one (the closing
  /// motion), not only the first closed frame.
  bool all_closing_frames = false;
  /// Test hook: a candidate for which this returns true fails as a failed simulation would.
  std::function<bool(const ValveParameters&)> force_failure;
};

/// One candidate's evaluation.
struct Evaluation {
  bool ok = false;
  /// kConverged when ok; else the simulation's outcome, kNonFiniteState for non-finite
  /// distances, kInvalidInput for anything else refused (a mvtwin::Error).
  Outcome outcome = Outcome::kInvalidInput;
  std::string reason;  ///< why it failed
  /// Point-to-mesh distances, mm, in a fixed order: per compared frame, the observed grid
  /// points (annulus row excluded: it is prescribed) to the simulated surface, then the
  /// simulated grid points to the observed surface (so a valve that stays open is seen).
  Eigen::VectorXd residuals;
  double mean_mm = 0;  ///< mean of the distances (symmetric point-to-mesh error)
  double wall_s = 0;
  bool cached = false;
};

/// The distance between a patient's observed closing surface(s) and the closure simulated
/// with candidate parameters. Thread-safe: candidates may be evaluated concurrently, each
/// simulation with its own state; repeated points come from a cache.
class ClosureObjective {
 public:
  /// Throws mvtwin::Error when the patient has no observed surface after end-diastole (a
  /// virtual patient needs `mvtwin phantom --simulate-closure`) or the options are invalid.
  ClosureObjective(const Patient& patient, ParameterSpace space, ObjectiveOptions options = {});

  const ParameterSpace& space() const { return space_; }
  const Patient& patient() const { return *patient_; }
  const ObjectiveOptions& options() const { return options_; }
  const std::vector<int>& frames() const { return frames_; }
  int num_residuals() const { return num_residuals_; }

  /// Never throws for a failed simulation: the evaluation says ok = false and why.
  Evaluation evaluate(const Eigen::VectorXd& x);
  /// Evaluates the candidates `jobs` at a time (TBB), in input order.
  std::vector<Evaluation> evaluate_many(const std::vector<Eigen::VectorXd>& xs, int jobs);

  int simulations() const;
  int failed_simulations() const;
  /// Failed simulations by outcome (outcome_name -> count); empty when none failed.
  std::map<std::string, int> failures_by_outcome() const;
  int cache_hits() const;

  /// The simulated closure at x (not cached), e.g. for the before/after files.
  forward::ClosureResult simulate(const Eigen::VectorXd& x) const;
  /// The distances of a closure simulated elsewhere (e.g. by simulate(x)) to the observation,
  /// as evaluate would give them; not counted and not cached. A failed simulation gives ok =
  /// false and its reason.
  Evaluation compare(const forward::ClosureResult& result) const;

 private:
  Evaluation compute(const Eigen::VectorXd& x) const;
  forward::ClosureOptions simulation_options() const;

  const Patient* patient_;
  ParameterSpace space_;
  ObjectiveOptions options_;
  std::vector<int> frames_;
  std::vector<TriangleMesh> observed_meshes_;
  std::vector<Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> observed_points_;
  int num_residuals_ = 0;
  int simulated_points_per_frame_ = 0;

  mutable std::mutex mutex_;
  std::map<std::vector<double>, Evaluation> cache_;
  int simulations_ = 0, failed_ = 0, hits_ = 0;
  std::map<std::string, int> failures_;
};

}  // namespace mvtwin::inverse
