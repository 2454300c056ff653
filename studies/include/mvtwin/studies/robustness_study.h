#pragma once
// The robustness study: the simulator under randomized abuse. Each case draws a virtual patient
// and extreme inputs (rest lengths x0.5-1.5, chordae stiffness and leaflet moduli x0.2-5, peak
// pressure 0-200 mmHg, dt 0.001-0.1 s, and in a third of the cases noisy or degenerate
// anatomy), simulates it and classifies the outcome: converged, clean failure (a status with a
// reason, or a named input error), crash (any other exception) or non-finite output. The only
// acceptable outcomes are the first two.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "mvtwin/forward/closure_simulation.h"
#include "mvtwin/studies/study_folder.h"
#include "mvtwin/studies/work_pool.h"

namespace mvtwin::studies {

struct RobustnessStudyOptions {
  std::filesystem::path out;
  int runs = 200;
  std::uint64_t seed = 7;
  forward::ClosureOptions model = coarse_model();  ///< dt is drawn per case
  int jobs = 2;
  std::string command;
  StudyProgress progress;

  /// 20 x 10: abuse is about the solver's guards, not resolution; it keeps the study fast.
  static forward::ClosureOptions coarse_model();
  bool is_valid(std::string* error) const;
  /// The test size: 12 cases on a 12 x 8 model.
  static RobustnessStudyOptions quick();
  nlohmann::json config() const;
};

struct RobustnessCase {
  int index = 0;
  std::uint64_t patient_seed = 0;
  std::string anatomy;  ///< clean, noisy or degenerate
  double dt = 0, peak_pressure_mmhg = 0;
  std::string outcome;  ///< converged, clean_failure, crash, nonfinite_output
  std::string reason;
  /// A clean failure's typed outcome (outcome_name: inverted_element, leaflet_crossing, ...;
  /// invalid_input for an input refused with mvtwin::Error); empty otherwise.
  std::string failure_kind;
  double wall_s = 0;
};

struct RobustnessStudyResult {
  std::vector<RobustnessCase> cases;
  int converged = 0, clean_failures = 0, crashes = 0, nonfinite = 0;
  std::string workers;
  double wall_s = 0;
};

/// Runs (or resumes) the study and, on the root, writes OUT/study.json, study.h5, plots and
/// report.md/.html. Case i is the same whatever process or thread runs it and whether or not
/// others were run before (its draws come from its own generator, seeded from `seed` and i).
RobustnessStudyResult run_robustness_study(const RobustnessStudyOptions& options, WorkPool& pool);

}  // namespace mvtwin::studies
