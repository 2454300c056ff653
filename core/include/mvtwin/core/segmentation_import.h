#pragma once
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/image_volume.h"
#include "mvtwin/core/patient.h"
#include "mvtwin/core/point_to_mesh_distance.h"

namespace mvtwin {

/// Label values of a valve segmentation (defaults: the mvtool convention).
struct SegmentationLabels {
  int annulus = 1;
  int anterior = 2;
  int posterior = 3;
};

struct SegmentationImportOptions {
  SegmentationLabels labels;
  /// Output grid.
  int ures = 30;
  int vres = 30;
  /// Direction into the left atrium in image space. When empty it is inferred: a closed valve's
  /// leaflets lie on the ventricular side of the annulus plane (tenting).
  std::optional<Eigen::Vector3d> atrial_direction;
  /// Pixel size of the atrial height field in mm.
  double pixel_mm = 0.5;
  /// Keep the label map in the patient file (images/volume_0000).
  bool keep_label_map = true;

  bool is_valid(std::string* error) const;
};

/// A closed valve fitted to a label map, and how well it fits.
struct SegmentationImport {
  /// One closed frame (first_closed = 0, end_diastole unknown): annulus, commissures,
  /// posterior annulus mid-point, both leaflet tips, and the LA surface on the (u,v) grid.
  /// Trigones and papillary tips are not visible in a leaflet segmentation: unobserved.
  Patient patient;
  /// Fitted surface vertices -> boundary of the leaflet mask (voxel faces), mm.
  DistanceStats surface_to_mask;
  /// Atrial-facing boundary faces of the leaflet mask -> fitted surface, mm.
  DistanceStats mask_to_surface;
  /// Fitted annulus curve -> annulus voxel centres, mm.
  DistanceStats annulus_to_mask;
  int annulus_voxels = 0, anterior_voxels = 0, posterior_voxels = 0;
  /// How choices were made (atrial side, commissures), for the report.
  std::vector<std::string> notes;
};

/// Fits the anatomical valve model to a label map. Throws mvtwin::Error naming `source` for a
/// label that is absent or too small, or a mask that gives no coaptation line.
SegmentationImport import_segmentation(const ImageVolume& label_map, const std::string& source,
                                       const SegmentationImportOptions& options = {});

}  // namespace mvtwin
