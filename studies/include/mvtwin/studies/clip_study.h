#pragma once
// The clip study: over a cohort, the residual regurgitant orifice before any clip, after the
// best single edge-to-edge clip and after the best pair of clips among candidate sites along the
// coaptation line (inverse/clip_prediction.h); how often two clips beat one, and how far apart
// the clipped leaflets' atrial surfaces end (the clip gap).
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mvtwin/core/valve_parameters.h"
#include "mvtwin/forward/closure_simulation.h"
#include "mvtwin/studies/cohort_study.h"
#include "mvtwin/studies/study_folder.h"
#include "mvtwin/studies/work_pool.h"

namespace mvtwin::studies {

struct ClipStudyOptions {
  std::filesystem::path out;
  /// Virtual patients (cohort_member's rule), simulated with their hidden parameters: what a
  /// perfect calibration would predict. Or every *.h5 patient file in `folder` (real ones
  /// included) at the default parameters.
  int patients = 10;
  std::uint64_t seed = 2026;
  std::filesystem::path folder;
  forward::ClosureOptions model;  ///< the paper's grid by default
  ValveParameters defaults;       ///< for patient files
  /// Single clips at these positions along the coaptation line (0 = anterolateral commissure,
  /// 1 = posteromedial), at the free edges; pairs of them at least `pair_spacing` apart.
  std::vector<double> positions = {0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8};
  bool pairs = true;
  double pair_spacing = 0.2;
  /// Two clips "win" when the best pair leaves at least this much less orifice than the best
  /// single clip, mm^2.
  double two_clip_margin_mm2 = 1.0;
  ClosureRating rating;
  int jobs = 2;
  std::string command;
  StudyProgress progress;

  bool is_valid(std::string* error) const;
  /// The test size: 2 patients on a coarse model (16 x 12, dt 0.02 s), clips at 0.3, 0.5,
  /// 0.7 and their pair 0.3 + 0.7.
  static ClipStudyOptions quick();
  nlohmann::json config() const;
  /// The candidate site sets, singles first, in the order the study simulates them.
  std::vector<std::vector<double>> candidates() const;
};

/// One simulated scenario of one patient (no clip, a single clip or a pair).
struct ClipStudyScenario {
  std::vector<double> positions;  ///< empty: no clip
  std::string status = "ok", reason;
  double orifice_mm2 = 0, coaptation_mm = 0, coapting_fraction = 0;
  int orifice_components = 0;
  double max_clip_gap_mm = 0;  ///< the largest over its clips at the end (0 without clips)
  double wall_s = 0;
};

struct ClipStudyPatient {
  std::string id, pathology, parameters_from;
  bool synthetic = false;
  std::string status = "ok", reason;         ///< failed when the unclipped closure failed
  std::vector<ClipStudyScenario> scenarios;  ///< no clip first, then candidates() in order
  int best_single = -1, best_pair = -1;      ///< indices into scenarios (-1: none converged)
  bool two_clips_win = false;
  std::string rating_before, rating_single, rating_pair;
};

struct ClipStudyResult {
  std::vector<ClipStudyPatient> patients;
  nlohmann::json summary;
  std::string workers;
  double wall_s = 0;
};

/// Runs (or resumes: each scenario is a record) the study and, on the root, writes
/// OUT/study.json, study.h5, plots and report.md/.html. Scenarios of every patient spread over
/// the pool (dynamic balancing), `jobs` at a time in each process.
ClipStudyResult run_clip_study(const ClipStudyOptions& options, WorkPool& pool);

}  // namespace mvtwin::studies
