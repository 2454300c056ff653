#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/image_volume.h"
#include "mvtwin/core/regurgitant_orifice.h"
#include "mvtwin/core/valve_parameters.h"
#include "mvtwin/core/valve_sequence.h"

namespace mvtwin {

/// What produced a file: written as attributes of its root group.
struct Provenance {
  std::string version;      ///< mvtwin version and commit
  std::string command;      ///< the command line (or function) that produced it
  std::string created_utc;  ///< ISO 8601
  std::uint64_t seed = 0;   ///< random seed, 0 when none was used
  std::string source;       ///< e.g. "virtual patient generator", "segmentation import: 008_gt"
};

/// Disease classes of virtual patients (docs/virtual-patients.md).
enum class Pathology : int {
  kNormal = 0,
  kProlapseElongatedChordae = 1,
  kProlapseRupturedChordae = 2,
  kFunctionalMr = 3,  ///< dilated annulus, tethered leaflets
  kStiffLeaflets = 4,
};
inline constexpr int kNumPathologies = 5;
std::string_view pathology_name(Pathology p);
/// Throws mvtwin::Error for an unknown name.
Pathology pathology_from_name(std::string_view name);

/// The hidden truth of a virtual patient: what calibration must recover, and how its anatomy
/// was drawn. Never present for a real patient.
struct VirtualTruth {
  Pathology pathology = Pathology::kNormal;
  ValveParameters parameters;
  /// Valve frame -> image space (the anatomy was drawn in a valve-centred frame: x towards
  /// the anterior annulus, y towards the anterolateral commissure, z into the atrium).
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
  /// Named anatomy draws (e.g. "ap_diameter_ed_mm"), for the record.
  std::vector<std::pair<std::string, double>> anatomy;
  /// The anatomy draw of that name; `absent` when the patient does not record it (files of an
  /// earlier generator edition lack the later names).
  double anatomy_or(std::string_view name, double absent) const {
    for (const auto& [quantity, v] : anatomy)
      if (quantity == name) return v;
    return absent;
  }
  /// How the frames whose leaflets are not geometric (closing and closed) were produced.
  std::string closed_frames = "missing: closed frames need the forward simulator";
  /// Which setting of the observation model observed them: empty for the model as given, else
  /// the safer retry that did after it failed (forward::observation_attempts).
  std::string observed_with;
  /// The regurgitant orifice of that simulation's closed valve: the true orifice, which the
  /// noisy closed frames only hint at (ground_truth/orifice). Empty until they are simulated.
  std::optional<RegurgitantOrifice> closed_orifice;
};

/// Everything mvtwin knows about one patient, real or virtual: the content of a patient file
/// (docs/patient-file.md).
struct Patient {
  std::string id;
  /// True for virtual patients. Every file of a synthetic patient says so.
  bool synthetic = false;
  ValveSequence sequence;
  Provenance provenance;
  std::optional<VirtualTruth> truth;
  /// Optional image volumes (one per frame for 3D+t).
  std::vector<ImageVolume> images;
  /// The valve as detected in `images` (mvtwin detect), kept beside `sequence` (for a virtual
  /// patient: the ground truth), never over it; `detected_by` names the model and its run.
  std::optional<ValveSequence> detected;
  std::string detected_by;
  /// For an imported patient: how each frame was fitted (errors, what was observed, estimated
  /// or assumed), as printed by mvtwin import and shown by mvtwin info. Empty otherwise.
  std::string import_report;
};

}  // namespace mvtwin
