#pragma once
#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/image_volume.h"
#include "mvtwin/core/valve_sequence.h"
#include "mvtwin/detection/segmentation_labels.h"

namespace mvtwin::detection {

/// How a valve frame is turned into a label map (a synthetic segmentation, to test the import
/// against a known valve).
struct LabelMapOptions {
  /// Values to write; annulus 0 writes no annulus label, papillary 0 no papillary label.
  SegmentationLabels labels;
  double voxel_mm = 0.5;
  /// Room around the valve, mm.
  double margin_mm = 4.0;
  /// Leaflet thickness (the FE model's, Mansi et al. 2012 Sec. 2.2), extruded from the atrial
  /// surface towards the ventricle, mm.
  double al_thickness_mm = 1.32;
  double pl_thickness_mm = 1.26;
  /// Radius of the annulus tube around the annulus curve, mm (it overrides the leaflets there,
  /// as in manual segmentations).
  double annulus_radius_mm = 1.5;
  /// Papillary muscle: a sphere of this radius whose atrial-most point is the tip, mm.
  double papillary_radius_mm = 3.0;
  /// Partial-volume boundary noise: a voxel is labelled when the fraction of it inside the
  /// structure plus N(0, boundary_noise) reaches 1/2 (only voxels the boundary crosses).
  double boundary_noise = 0.15;
  /// Sub-samples per voxel and axis for the partial-volume fraction.
  int supersample = 3;
  std::uint64_t seed = 1;
  /// Voxel axes (columns, orthonormal); identity when empty.
  std::optional<Eigen::Matrix3d> direction;
  /// The image geometry (size, spacing, origin, direction; data ignored) to rasterize into,
  /// e.g. a box shared by every frame of a sequence; by default a box around the frame.
  std::optional<ImageVolume> geometry;

  bool is_valid(std::string* error) const;
};

/// Rasterizes one frame: the leaflets (the atrial surface extruded by the thickness along its
/// normals, each leaflet with its label), the annulus tube and the papillary muscles (when
/// their labels are set and the frame has the tips). Throws mvtwin::Error for a frame without a
/// leaflet surface or invalid options.
ImageVolume valve_label_map(const ValveFrame& frame, const LabelMapOptions& options);

/// The default geometry of valve_label_map (no data): a box in the voxel axes around
/// everything drawn, its origin on the lattice of `voxel_mm` so that boxes of several frames
/// share voxel centres.
ImageVolume label_map_geometry(const ValveFrame& frame, const LabelMapOptions& options);

/// The smallest geometry holding every one of `boxes` (same spacing and axes).
ImageVolume union_geometry(const std::vector<ImageVolume>& boxes);

}  // namespace mvtwin::detection
