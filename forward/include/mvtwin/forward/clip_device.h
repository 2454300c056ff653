#pragma once
#include <string>
#include <string_view>
#include <vector>

namespace mvtwin::forward {

/// An edge-to-edge repair device as the model sees it: one row of the device table
/// (forward/data/clip_devices.json, compiled in; docs/clip-devices.md). Lengths in mm.
struct ClipDevice {
  std::string name;    ///< e.g. "XTW", "P10"
  std::string family;  ///< "MitraClip G4", "PASCAL Precision"
  std::string maker;
  std::string grasp;         ///< "arm and gripper", "paddle and clasp"
  double width_mm = 0;       ///< arm or paddle width along the coaptation line
  double arm_length_mm = 0;  ///< the longest leaflet insertion the arm holds
  double spacer_mm = 0;      ///< between the grasped leaflets (0: held against each other)
  bool verified = false;     ///< checked against the instructions for use
  std::string source;
};

/// A clip of a closure simulation (Mansi et al. 2012, Sec. 2.4) between a site on each leaflet, in
/// grid coordinates (s in [0, 1) around the annulus from the anterolateral commissure, anterior for
/// s < 0.5; t from the annulus (0) to the free edge (1)).
///
/// With width_mm = 0 it is the paper's clip: a stiff tension-only spring between the two sites'
/// cross-sections, holding their atrial surfaces the contact distance apart.
///
/// With a width it is a device (forward/clip_device.h): it grasps a band of each leaflet, width_mm
/// wide along the coaptation line around the site and as deep from the free edge as the leaflet
/// inserts into the arm (anterior_/posterior_insertion_mm, or from the geometry at the grasp
/// capped by arm_length_mm: ClipGrasp), and holds the two bands face to face, spacer_mm apart (at
/// least the contact distance), by stiff two-way ties between facing cross-sections and their
/// neighbours: the grasped tissue moves together and floats with the valve. The sites' t is not
/// used.
struct ClipOptions {
  double anterior_s = 0.25, anterior_t = 1.0;
  double posterior_s = 0.75, posterior_t = 1.0;
  double stiffness_n_per_mm = 9.80665;  ///< 1000 gf/mm (Mansi et al. 2012), per tie of a device
  double width_mm = 0.0;                ///< grasp width along the line; 0: the paper's spring
  double arm_length_mm = 0.0;           ///< the longest insertion the arm holds
  double spacer_mm = 0.0;               ///< between the grasped leaflets' atrial surfaces
  /// Leaflet insertions, mm; 0: from the geometry at the grasp (clip_insertion_mm).
  double anterior_insertion_mm = 0.0, posterior_insertion_mm = 0.0;
  std::string device;  ///< its name (ClipDevice), for the record
};

/// How a clip grasped the leaflets (ClosureScene::grasps, ClosureResult::clip_grasps).
struct ClipGrasp {
  std::string device;
  /// Leaflet length inside the arm, mm: the tissue left after spanning from the annulus to the
  /// coaptation point, L (L + Lp - chord) / (L + Lp), from the end-diastolic leaflet lengths at
  /// the sites and their annulus chord at the first closed frame, capped by the arm (or
  /// ClipOptions::anterior_insertion_mm, posterior_insertion_mm).
  double anterior_insertion_mm = 0, posterior_insertion_mm = 0;
  int anterior_nodes = 0, posterior_nodes = 0;  ///< surface nodes grasped on each leaflet
  int ties = 0;
  /// The stretch of the coaptation line (0 anterolateral, 1 posteromedial commissure) the
  /// device's body fills: from its grasped bands (empty for the paper's spring).
  double line_begin = 0, line_end = 0;
  /// The grasped surface nodes of each leaflet (the model's surface node indices).
  std::vector<int> anterior_band, posterior_band;
  /// The elements of the corner mesh near the grasp: a corner within kGraspStressMarginMm of a
  /// grasped node in the unrolled leaflet plane (where the stress near the grasp is taken).
  std::vector<int> region_elements;
};

/// The margin around a grasped band within which the leaflet stress is taken, mm (issue 39: the
/// grasped band and 3 mm around it).
inline constexpr double kGraspStressMarginMm = 3.0;

/// Every device of the table, in its order.
const std::vector<ClipDevice>& clip_devices();
/// The device of that name (case-insensitive); throws mvtwin::Error listing the known names.
const ClipDevice& clip_device(std::string_view name);

}  // namespace mvtwin::forward
