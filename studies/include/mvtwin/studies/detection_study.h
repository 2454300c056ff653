#pragma once
// The detection study: the valve detector on synthetic 3D+t TEE of a held-out virtual cohort.
// Two disjoint cohorts are drawn (pathologies in turn); their closing frames are simulated
// without noise (the truth to detect) and every frame is rendered as TEE. A detector is trained
// on the first cohort (or a given model is checked to have seen none of the second) and run on
// the second at each noise level: point-to-mesh error of the detected leaflets per frame and
// phase, landmark and papillary-tip errors, time per volume, and the curve of error against
// noise.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mvtwin/detection/tee_renderer.h"
#include "mvtwin/detection/valve_detector.h"
#include "mvtwin/studies/study_folder.h"
#include "mvtwin/studies/virtual_tee.h"
#include "mvtwin/studies/work_pool.h"

namespace mvtwin::studies {

struct DetectionStudyOptions {
  std::filesystem::path out;  ///< the study folder (resumable)
  /// Training patients are members 0..train-1 of the cohort `seed`, test patients members
  /// 500, 501, ... (disjoint while train <= 500).
  std::uint64_t seed = 3030;
  int train = 12, test = 6;
  /// Electronic noise SDs of the test renders; the first is the headline (the default
  /// acquisition). More levels or test patients extend a finished study.
  std::vector<double> noise_levels{0.004, 0.0, 0.016, 0.063, 0.25};
  /// The training renders' noise (patients cycle through the levels).
  std::vector<double> train_noise = kTrainingNoise;
  detection::TeeRenderOptions render = default_render();  ///< its noise is set per level
  detection::DetectorOptions detector;
  /// name=value changes to the model simulating the truth (the calibration model by default).
  std::vector<std::string> truth_sets;
  /// Evaluate this model (mvtwin train-detector) instead of training one; it must not have
  /// seen a test patient.
  std::filesystem::path model_file;
  /// Where the truths and the trained detector are kept (default OUT/cache), shared by runs.
  std::filesystem::path cache;
  int jobs = 2;  ///< patients at once in each process
  std::string command;
  StudyProgress progress;

  /// The default acquisition with 10 degrees of probe pose variation between patients.
  static detection::TeeRenderOptions default_render();
  bool is_valid(std::string* error) const;
  /// The test size: 3 training and 1 test patient, 2.5 mm voxels and a wider PSF (coarse
  /// images, cheap to render), small forests, a 16 x 8 truth model, noise levels 0.004 and 0.1.
  static DetectionStudyOptions quick();
  /// What decides the numbers (not the noise levels or the test count: each detection
  /// depends only on its patient and level).
  nlohmann::json config() const;
};

/// One detection: a test patient at one noise level.
struct DetectionRun {
  int patient = 0;  ///< index in the test cohort
  std::uint64_t patient_seed = 0;
  std::string id, pathology;
  double noise = 0;
  bool ok = false;
  std::string reason;
  nlohmann::json frames;  ///< per frame (detection_errors)
  nlohmann::json to_json() const;
  static DetectionRun from_json(const nlohmann::json& j);
};

struct DetectionStudyResult {
  std::vector<DetectionRun> runs;
  /// Per noise level (summarize_detections plus "noise"), in the order of noise_levels.
  nlohmann::json curve = nlohmann::json::array();
  nlohmann::json headline;  ///< the first level's entry of `curve`
  /// The detector: its file, and when trained by this study, the training figures.
  std::filesystem::path detector_file;
  std::vector<std::string> training_patients;
  int training_volumes = 0;
  double train_s = 0;
  std::string workers;
  double wall_s = 0;
};

/// Runs (or resumes) the study over the pool's processes and, on the root, writes
/// OUT/study.json, study.h5 (one row per detected frame), the plots and report.md/.html. The
/// root trains the detector (cached by everything that makes it); detections are spread over
/// the processes. Throws mvtwin::Error for invalid options, a model that saw a test patient, or
/// an OUT holding another study; a patient that fails is recorded and the study goes on.
DetectionStudyResult run_detection_study(const DetectionStudyOptions& options, WorkPool& pool);

}  // namespace mvtwin::studies
