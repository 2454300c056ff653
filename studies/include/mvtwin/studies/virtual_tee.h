#pragma once
// Virtual patients with synthetic TEE for training and testing the valve detector: the
// closing frames simulated (the truth to detect), every frame rendered. Shared by
// mvtwin train-detector --virtual and the detection study.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "mvtwin/core/patient.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/detection/tee_renderer.h"
#include "mvtwin/detection/valve_detector.h"
#include "mvtwin/forward/virtual_closure.h"

namespace mvtwin::studies {

/// How the truth is made: the closing frames simulated by the calibration model's defaults
/// changed by `sets` (name=value), without noise (the surfaces the images are rendered from).
struct VirtualTeeTruth {
  explicit VirtualTeeTruth(const std::vector<std::string>& sets = {});
  forward::VirtualClosureOptions closure;
  std::string key;  ///< names cached truth files by the model that made them
};

/// Seed of patient i (0-based) of the virtual cohort `cohort_seed`: the rule of every command
/// (mvtwin::cohort_member), so that train-detector --virtual and the detection study draw the same
/// patients (and share caches).
inline std::uint64_t virtual_cohort_seed(std::uint64_t cohort_seed, int i) {
  return cohort_member(cohort_seed, i).seed;
}

/// Virtual patient `seed` (pathology `i % kNumPathologies`) with its closing frames simulated.
/// With a `cache` directory the patient is read from it when there, else written to it (HDF5
/// calls hold hdf5_mutex()). Throws mvtwin::Error when the simulation fails.
Patient virtual_tee_patient(std::uint64_t seed, int i, const VirtualTeeTruth& truth,
                            const std::filesystem::path& cache);

/// The patient's frames rendered with `render` (its noise as given), the speckle seeded by the
/// patient's seed.
std::vector<ImageVolume> render_virtual_tee(const Patient& patient,
                                            detection::TeeRenderOptions render);

/// The training renders' noise levels by default: the default acquisition, 4x and 16x its
/// electronic noise, and none (patients cycle through them).
inline const std::vector<double> kTrainingNoise = {0.004, 0.016, 0.063, 0.0};

struct VirtualTrainingResult {
  detection::ValveDetector detector;
  std::vector<std::string> patients;  ///< ids used
  int volumes = 0;
  double prepare_s = 0;  ///< simulating and rendering
  double train_s = 0;
};

/// Trains a detector on the virtual patients `seeds` (each rendered; every frame with a known
/// surface is one training volume), `jobs` patients prepared at once. Patient k is rendered
/// with the electronic noise `noise[k % noise.size()]` (images of varied quality; `render`'s
/// own noise when empty). A patient whose simulation fails is skipped and said so. Progress
/// lines go to `log` (called from one thread at a time).
VirtualTrainingResult train_on_virtual_cohort(const std::vector<std::uint64_t>& seeds,
                                              const VirtualTeeTruth& truth,
                                              const detection::TeeRenderOptions& render,
                                              const std::vector<double>& noise,
                                              const detection::DetectorOptions& options, int jobs,
                                              const std::filesystem::path& cache,
                                              const std::function<void(const std::string&)>& log);

/// A detection of `truth`'s images against its stored valve: per frame, its phase, the detection
/// time, the surface error (symmetric point-to-mesh, where the frame has a known surface) and
/// each observed landmark's distance (JSON array of frames).
nlohmann::json detection_errors(const Patient& truth, const std::vector<ValveFrame>& detected,
                                const std::vector<detection::DetectionInfo>& info);

/// Figures over detections (objects with "frames" from detection_errors): surface error mean
/// and SD over frames, by phase, the SD of the patients' means, per landmark, papillary tips,
/// s per volume.
nlohmann::json summarize_detections(const std::vector<const nlohmann::json*>& runs);

}  // namespace mvtwin::studies
