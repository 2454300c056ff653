#pragma once
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/leaflet_grid.h"

namespace mvtwin {

/// Mitral regurgitation grade from the effective regurgitant orifice area (ASE 2017, Zoghbi et
/// al., J Am Soc Echocardiogr 30:303, applied to primary and secondary MR alike): mild < 20,
/// moderate 20-39, severe >= 40 mm^2. Below 1 mm^2 no orifice is resolved: none.
enum class MrGrade : int { kNone = 0, kMild = 1, kModerate = 2, kSevere = 3 };
std::string_view mr_grade_name(MrGrade g);
MrGrade mr_grade_of(double eroa_mm2);

/// How the regurgitant orifice is measured.
struct OrificeOptions {
  /// Leaflets closer than this seal (mm). A simulated valve's seal is its contact law's reach,
  /// the distance below which the leaflets push on each other (forward::SelfContactOptions::
  /// contact_mm): closer leaflets carry the pressure across, farther ones do not touch.
  double seal_mm = 0.3;
  /// EROA = contraction_coefficient x AROA: the vena contracta of the jet through a sharp-edged
  /// slit is pi / (pi + 2) = 0.611 of the slit (Kirchhoff's free-streamline solution; the
  /// regurgitant orifices of closed valves are slits along the coaptation line; Yoganathan et
  /// al. 1988, J Am Coll Cardiol 12:1344 give 0.6-0.7 for valve orifices).
  double contraction_coefficient = 0.611;
  /// Share of the coaptation line, centred, over which coaptation length and depth are taken
  /// (the commissural ends are left out, as in echo's A2-P2 measurement).
  double central_fraction = 0.7;
  /// Stretches of the coaptation line [begin, end] (as Opening::begin) that a clip device's
  /// body fills: cut out of the openings whatever the gap (the device holds the leaflets apart
  /// but blocks the flow), exactly at their ends, also between columns; the columns keep their
  /// measured gaps.
  std::vector<std::pair<double, double>> blocked;

  bool is_valid(std::string* error) const;
};

/// One opening: a stretch of the coaptation line where the leaflets do not seal.
struct Opening {
  double area_mm2 = 0;  ///< anatomic area
  /// Where along the coaptation line, 0 = anterolateral commissure, 1 = posteromedial (the
  /// position a clip is placed at).
  double begin = 0, end = 0;
  double length_mm = 0;   ///< along the line (the flail or gap width, EVEREST)
  double max_gap_mm = 0;  ///< widest gap between the leaflets (the flail gap, EVEREST)
};

/// The narrowest gap of one leaflet column to the other leaflet.
struct ColumnGap {
  double position = 0;   ///< along the coaptation line (as Opening::begin)
  double gap_mm = 0;     ///< distance to the other leaflet's atrial surface
  Eigen::Vector3d a, b;  ///< the column's point and the other leaflet's closest point
  bool anterior = true;  ///< the column's leaflet
};

/// The anatomic regurgitant orifice of a closed valve and the measures that go with it.
struct RegurgitantOrifice {
  double aroa_mm2 = 0;  ///< anatomic regurgitant orifice area, the sum of the openings
  double eroa_mm2 = 0;  ///< contraction_coefficient x aroa
  MrGrade grade = MrGrade::kNone;
  std::vector<Opening> openings;  ///< largest first
  /// Coaptation over the central columns of the anterior leaflet (OrificeOptions::
  /// central_fraction): the length along its atrial surface sealed against the posterior leaflet
  /// (median over the columns that coapt; 0 when none does), and the depth of the first sealed
  /// point below the annulus plane (median; NaN when none coapts).
  double coaptation_length_mm = 0;
  double coaptation_depth_mm = 0;
  double coapting_fraction = 0;    ///< of the central columns, the share that coapt
  std::vector<ColumnGap> columns;  ///< both leaflets, along the line
  OrificeOptions options;
};

/// Measures the anatomic regurgitant orifice area (AROA) of a closed valve from its atrial
/// surface and, when given, its ventricular surface on the same grid (the leaflet solid's other
/// side): the area through which blood can pass from the ventricle to the atrium.
///
/// The closed valve is a flattened tube: the anterior and posterior atrial surfaces face each
/// other across a slit that runs from commissure to commissure. For every column of each
/// leaflet the narrowest gap g to the other leaflet is found (3D distance, so a tilted or
/// overlapping slit is measured across, not along a line of sight; with the ventricular surface,
/// between the two leaflet solids, so that a leaflet folded over the other, touching it with its
/// ventricular side, seals as the contact law sees it); where g <= seal_mm the leaflets seal. Along
/// the line the open part integrates g over the column spacing (trapezoids, the seal crossing
/// placed by linear interpolation between columns), for each leaflet's columns; the AROA is the
/// mean of the two leaflets' integrals. The commissure columns belong to both leaflets (gap 0). For
/// a slit of width w > seal_mm and length L this gives w L whatever its tilt
/// (tests/core/regurgitant_orifice_test.cpp). Use a grid fine enough for the gap to be resolved
/// (resample a coarse one: LeafletGrid::resampled).
///
/// Throws mvtwin::Error for invalid options or non-finite coordinates.
RegurgitantOrifice measure_regurgitant_orifice(const LeafletGrid& la_surface,
                                               const OrificeOptions& options = {},
                                               const LeafletGrid* lv_surface = nullptr);

}  // namespace mvtwin
