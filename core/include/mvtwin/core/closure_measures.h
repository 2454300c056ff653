#pragma once
#include <Eigen/Core>

#include "mvtwin/core/triangle_mesh.h"
#include "mvtwin/core/valve_sequence.h"

namespace mvtwin {

/// How well a valve closes, seen from the atrium.
struct ClosureMeasures {
  double annulus_area_mm2 = 0.0;  ///< the annulus opening projected on its plane
  /// Regurgitant orifice: the part of the annulus opening that a ray from the atrium, along the
  /// annulus-plane normal, crosses without hitting a leaflet (mm^2).
  double orifice_area_mm2 = 0.0;
  double resolution_mm = 0.0;     ///< pixel size of the rasterization
  int orifice_components = 0;     ///< separate openings (2 after a successful clip, 0 if closed)
};

/// Rasterizes the annulus opening (annulus curve projected on its least-squares plane) at
/// `resolution_mm` and the leaflet surface projected the same way; pixels of the opening not
/// covered by a leaflet triangle form the orifice. Openings smaller than `min_component_mm2`
/// (pixel noise along the annulus) are not counted as separate components, and are left out
/// of the area. Throws mvtwin::Error for an empty surface, a degenerate annulus or a resolution
/// outside (0.01, 5] mm.
ClosureMeasures measure_closure(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& annulus,
    const TriangleMesh& leaflets, double resolution_mm = 0.2, double min_component_mm2 = 0.5);

/// The same for a frame with a leaflet surface.
ClosureMeasures measure_closure(const ValveFrame& frame, double resolution_mm = 0.2);

}  // namespace mvtwin
