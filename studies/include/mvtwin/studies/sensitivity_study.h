#pragma once
// The sensitivity study (the paper's Sec. 4.2 and Figs 13-14): one patient's closure with the
// annulus or the papillary tips held still, with 56/28/20/16/12 marginal chordae, chordae
// stiffness and rest lengths +-30 %, each against the baseline: the leaflet tips' distance to
// the annulus plane over time, and its largest difference from the baseline.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "mvtwin/forward/closure_simulation.h"
#include "mvtwin/studies/study_folder.h"
#include "mvtwin/studies/work_pool.h"

namespace mvtwin::studies {

struct SensitivityStudyOptions {
  std::filesystem::path out;
  /// The patient: index `patient` of the virtual cohort `seed` (with its hidden parameters
  /// as the baseline), or a patient file (the default parameters).
  std::uint64_t seed = 2026;
  int patient = 0;
  std::filesystem::path patient_file;
  forward::ClosureOptions model;  ///< the baseline model (the paper's grid by default)
  /// Tip distances are recorded every this much observed time, s.
  double sample_s = 0.01;
  int jobs = 2;
  std::string command;
  StudyProgress progress;

  bool is_valid(std::string* error) const;
  /// The test size: a coarse model (16 x 12, dt 0.02 s).
  static SensitivityStudyOptions quick();
  nlohmann::json config() const;
};

/// One case: its group (motion, marginal chordae, stiffness, rest length), label and settings.
struct SensitivityCase {
  std::string group, label;
  std::vector<std::string> settings;  ///< name=value on the baseline (options or parameters)
  std::string status = "ok", reason;
  std::vector<double> time_s, anterior_tip_mm, posterior_tip_mm;  ///< observed time, mm
  double max_anterior_diff_mm = 0, max_posterior_diff_mm = 0;     ///< against the baseline
  double end_orifice_mm2 = 0, end_anterior_tip_mm = 0, end_posterior_tip_mm = 0;
  double wall_s = 0;
};

struct SensitivityStudyResult {
  std::string patient_id;
  bool synthetic = false;
  std::vector<SensitivityCase> cases;  ///< the baseline first
  std::string workers;
  double wall_s = 0;
};

/// The cases in order, baseline first.
std::vector<SensitivityCase> sensitivity_cases();

/// Runs (or resumes) the study and, on the root, writes OUT/study.json, study.h5, the tip plots
/// and report.md/.html. A case whose simulation fails is recorded with its reason.
SensitivityStudyResult run_sensitivity_study(const SensitivityStudyOptions& options,
                                             WorkPool& pool);

}  // namespace mvtwin::studies
