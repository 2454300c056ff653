#pragma once
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/image_volume.h"
#include "mvtwin/core/landmark.h"
#include "mvtwin/core/markups.h"
#include "mvtwin/core/patient.h"
#include "mvtwin/detection/segmentation_fit.h"

namespace mvtwin::detection {

/// One frame of the cycle, a label map or leaflet surface meshes, and its time.
struct LabelFrame {
  ImageVolume labels;
  double time_s = 0.0;
  std::string source;  ///< file name, for messages and the record
  /// Labels of this frame when they differ from the options' (a .seg.nrrd's segment names).
  std::optional<SegmentationLabels> labels_override;
  /// Leaflet surface meshes (anterior, posterior) in place of the label map (fit_surface_frame).
  std::optional<std::pair<TriangleMesh, TriangleMesh>> meshes;
};

/// A landmark placed in another tool: in one frame (time set) or in every frame.
struct LandmarkInput {
  Landmark landmark;
  Eigen::Vector3d position;  ///< RAS, mm
  std::optional<double> time_s;
  std::string source;
};

/// The landmark a markup label names ("anterolateral papillary tip", "ALPM", "PM papillary",
/// "left trigone", "AL commissure", "posterior annulus midpoint", ...; docs/import.md lists
/// them), or nothing.
std::optional<Landmark> landmark_from_label(std::string_view label);

/// Markups to landmarks: by label where every point's label names a landmark, else by
/// `order` (landmark names in the order of the points), else two points are the
/// anterolateral and posteromedial papillary tips. Throws mvtwin::Error naming the file for
/// points it cannot place.
std::vector<LandmarkInput> landmarks_from_markups(const MarkupList& markups,
                                                  const std::string& source,
                                                  std::optional<double> time_s,
                                                  const std::vector<Landmark>& order = {});

struct PatientImportOptions {
  SegmentationFitOptions fit;
  /// Frame indices (in time order); -1: from the leaflet opening (largest orifice before the
  /// smallest one, and the smallest).
  int end_diastole = -1;
  int first_closed = -1;
  std::string id;
  /// Frames' annuli may move, but a jump of the anterolateral commissure larger than this
  /// between frames means the grids disagree (mm).
  double max_commissure_jump_mm = 15.0;
  /// Torn marginal chordae seen in the images (a flail segment), as stretches of the grid
  /// coordinate s around the annulus (ValveSequence::ruptured_chordae); empty: none.
  std::vector<ChordaeRupture> ruptured_chordae;

  bool is_valid(std::string* error) const;
};

struct PatientImport {
  Patient patient;
  std::vector<FrameFit> fits;  ///< in time order
  std::vector<std::string> notes;
  /// What was estimated from published anatomy rather than observed.
  std::vector<std::string> assumed;
};

/// Builds a real patient from label maps of two or more frames (or one, which gives a patient
/// that can be measured but not simulated) and landmarks. Throws mvtwin::Error naming the file
/// and the problem (duplicate frame times, frames whose grids disagree, landmarks far outside
/// the valve, ...). Papillary tips that are neither labelled nor given are estimated from
/// published anatomy (26.5 mm below the annulus plane, 30 mm apart, 4 mm posterior;
/// docs/virtual-patients.md) and marked assumed.
PatientImport import_patient(std::vector<LabelFrame> frames,
                             const std::vector<LandmarkInput>& landmarks,
                             const PatientImportOptions& options);

}  // namespace mvtwin::detection
