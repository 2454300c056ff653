#pragma once
#include <Eigen/Core>

#include "mvtwin/core/valve_sequence.h"

namespace mvtwin {

/// Annulus size and shape of one frame, as reported in the echo literature
/// (docs/virtual-patients.md). All lengths in mm, areas in mm^2. Computed from the annulus curve
/// (refined by the periodic spline of the grid) and the grid convention (commissures at u = 0 and
/// ures/2).
struct AnnulusMeasures {
  double perimeter_mm = 0.0;
  /// Area of the triangle fan from the curve's centroid: the 3D annulus area.
  double area_3d_mm2 = 0.0;
  /// Area of the curve projected onto its least-squares plane.
  double area_projected_mm2 = 0.0;
  /// Saddle height: range of the curve's signed distances to its least-squares plane.
  double height_mm = 0.0;
  /// Distance between the two commissures (annulus points u = 0 and u = ures/2).
  double commissural_width_mm = 0.0;
  /// Antero-posterior (septal-lateral) diameter: from the posterior annulus mid-point
  /// (u = 3 ures/4) to the anterior annulus, perpendicular to the commissural line in the
  /// annulus plane.
  double ap_diameter_mm = 0.0;
  /// Antero-lateral/postero-medial diameter: the curve's largest extent along the commissural
  /// line, in the annulus plane.
  double alpm_diameter_mm = 0.0;
  /// Distance between the trigones, NaN when they were not observed.
  double intertrigonal_mm = 0.0;
  /// Arc lengths of the anterior (u in [0, ures/2]) and posterior annulus.
  double anterior_arc_mm = 0.0;
  double posterior_arc_mm = 0.0;
};

AnnulusMeasures annulus_measures(const ValveFrame& frame);

}  // namespace mvtwin
