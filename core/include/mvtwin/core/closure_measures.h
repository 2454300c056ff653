#pragma once
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/leaflet_grid.h"
#include "mvtwin/core/triangle_mesh.h"
#include "mvtwin/core/valve_sequence.h"

namespace mvtwin {

/// How well a valve closes, seen from the atrium.
struct ClosureMeasures {
  double annulus_area_mm2 = 0.0;  ///< the annulus opening projected on its plane
  /// Regurgitant orifice: the part of the annulus opening that a ray from the atrium, along the
  /// annulus-plane normal, crosses without hitting a leaflet (mm^2).
  double orifice_area_mm2 = 0.0;
  double resolution_mm = 0.0;  ///< pixel size of the rasterization
  int orifice_components = 0;  ///< separate openings (2 after a successful clip, 0 if closed)
  std::vector<double> component_areas_mm2;  ///< area of each opening, largest first
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

/// Coaptation of a closed valve: for each anterior column away from the commissures (the
/// middle 70 % of the anterior leaflet), the length along the column of the part of its atrial
/// surface within `contact_mm` of the posterior leaflet's atrial surface (the leaflets appose
/// atrial side to atrial side near their free edges).
struct Coaptation {
  double length_mm = 0;          ///< median over the columns that coapt
  double max_mm = 0;             ///< longest
  double coapting_fraction = 0;  ///< of the columns looked at, the share that coapt at all
};
Coaptation measure_coaptation(const LeafletGrid& la_surface, double contact_mm = 1.0);

/// The same for a frame with a leaflet surface.
ClosureMeasures measure_closure(const ValveFrame& frame, double resolution_mm = 0.2);

}  // namespace mvtwin
