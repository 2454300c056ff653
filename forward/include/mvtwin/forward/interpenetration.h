#pragma once
#include <vector>

#include <Eigen/Core>

#include "mvtwin/forward/valve_model.h"

namespace mvtwin::forward {

/// Surface nodes of one leaflet that lie inside the other leaflet.
struct Interpenetration {
  int checked = 0;         ///< surface nodes (corner and mid-edge, both surfaces) tested
  std::vector<int> nodes;  ///< those inside an element of the other leaflet
};

/// Tests every node of the model's atrial and ventricular surfaces against the elements of the
/// other leaflet (tags AL / PL) at positions x (all nodes, flattened, mm). Quadratic elements
/// are taken as their 8 linear sub-tetrahedra; a node counts as inside when all its barycentric
/// coordinates in one of them exceed `margin` (a node on the element's boundary, as at the
/// commissures where the leaflets meet, is not inside).
Interpenetration find_interpenetration(const ValveModel& model, const Eigen::VectorXd& x,
                                       double margin = 0.02);

}  // namespace mvtwin::forward
