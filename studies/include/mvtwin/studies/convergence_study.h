#pragma once
// The convergence study (the paper's Sec. 4.1 and Figs 10-12): one patient's closure over
// in-plane resolution (ures), radial resolution (vres), layers through the thickness and time
// step, one factor at a time around the base model, each run against the finest run of its
// series (symmetric point-to-mesh distance between the closed atrial surfaces), and every run's
// wall time against its error (the Pareto plot: what a faster model costs).
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "mvtwin/forward/closure_simulation.h"
#include "mvtwin/studies/study_folder.h"
#include "mvtwin/studies/work_pool.h"

namespace mvtwin::studies {

struct ConvergenceStudyOptions {
  std::filesystem::path out;
  /// The patient: index `patient` of the virtual cohort `seed` (its hidden parameters), or a
  /// patient file (the default parameters).
  std::uint64_t seed = 2026;
  int patient = 0;
  std::filesystem::path patient_file;
  forward::ClosureOptions model;  ///< the base model (the paper's grid by default)
  /// The series: each varies one factor of the base model; the last value is the reference
  /// (the finest) of its series. The paper's ranges by default.
  std::vector<int> ures = {20, 30, 40, 50};
  std::vector<int> vres = {10, 20, 30};
  std::vector<int> layers = {1, 2, 3};
  std::vector<double> dt = {0.1, 0.05, 0.01, 0.001, 0.0001};
  /// Every model is also run with these settings on top (name=value; empty: not paired), its
  /// error measured against the same references: by default the closed valve at rest by the
  /// static solve beside settling (issue 40).
  std::vector<std::string> pair = {"static_rest=on"};
  int jobs = 2;
  std::string command;
  StudyProgress progress;

  bool is_valid(std::string* error) const;
  /// The test size: a coarse base (12 x 8, dt 0.02 s) and two or three values per series.
  static ConvergenceStudyOptions quick();
  nlohmann::json config() const;
};

/// One run of a series.
struct ConvergenceRun {
  std::string factor;                 ///< ures, vres, layers or dt
  std::string value;                  ///< as given
  std::vector<std::string> settings;  ///< name=value on the base model
  bool reference = false;             ///< the finest of its series
  std::string status = "ok", reason;
  double wall_s = 0;
  int steps = 0, dofs = 0, tets = 0;
  double end_orifice_mm2 = 0;
  /// Against the series' reference, mm (NaN when either failed).
  double error_mean_mm = 0, error_sd_mm = 0, error_p95_mm = 0, error_max_mm = 0;
  /// The paired run (ConvergenceStudyOptions::pair; status empty when not paired): the same
  /// model with the pair's settings, against the same reference, and its end against this
  /// run's end (mean, mm). static_converged: whether its static solve converged (else settling
  /// finished it).
  std::string paired_status, paired_reason;
  double paired_wall_s = 0;
  int paired_steps = 0;
  bool paired_static_converged = false;
  double paired_error_mean_mm = 0, paired_error_max_mm = 0, paired_difference_mm = 0;
};

struct ConvergenceStudyResult {
  std::string patient_id;
  bool synthetic = false;
  std::vector<ConvergenceRun> runs;  ///< series by series, coarse to fine
  int simulations = 0;               ///< distinct models simulated (runs share the base model)
  std::string workers;
  double wall_s = 0;
};

/// Runs (or resumes) the study and, on the root, writes OUT/study.json, study.h5, the plots and
/// report.md/.html. A run whose simulation fails is recorded with its reason. Runs with the
/// same model (the base appears in every series) are simulated once.
ConvergenceStudyResult run_convergence_study(const ConvergenceStudyOptions& options,
                                             WorkPool& pool);

}  // namespace mvtwin::studies
