#pragma once
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/valve_parameters.h"
#include "mvtwin/core/valve_sequence.h"
#include "mvtwin/forward/chorda.h"
#include "mvtwin/forward/solid_mesh.h"

namespace mvtwin::forward {

/// How the finite-element model of a valve is built (SPEC Sec. 3).
struct ModelOptions {
  /// Grid of the model (the sequence is resampled to it; correspondence is kept).
  int ures = 30;
  int vres = 30;
  /// Element layers through the thickness.
  int layers = 1;
  /// Quadratic tetrahedra do not lock in bending at nu = 0.488; linear ones do (SPEC Sec. 4).
  TetOrder order = TetOrder::kQuadratic;
  /// Marginal chordae evenly on the free edge (the paper: 28; sensitivity: 56, 20, 16, 12).
  int marginal_chordae = 28;
  /// Leaflet thickness in mm (Mansi et al. 2012, after Votta 2008 / Kunzelman 2007).
  double al_thickness_mm = 1.32;
  double pl_thickness_mm = 1.26;

  bool is_valid(std::string* error) const;
};

/// One chorda of the model: from a leaflet node to a papillary tip.
struct ModelChorda {
  int node = -1;  ///< leaflet node on the ventricular surface at the insertion
  /// The insertion point is the mean of these nodes: the whole leaflet cross-section at the
  /// site (every layer and the mid-edge nodes between them), so that a taut chorda does not
  /// crush a single element.
  std::vector<int> nodes;
  int papillary = 0;  ///< 0 anterolateral, 1 posteromedial tip
  ChordaeGroup group = ChordaeGroup::kAnterolateralMarginal;
  bool marginal = true;
  int u = 0, v = 0;  ///< grid site of the insertion
  /// Insertion-point-to-tip distance at end-diastole, mm (rest length = this x factor).
  double ed_length = 0.0;
};

/// The finite-element model of a valve at end-diastole.
struct ValveModel {
  ModelOptions options;
  SolidMesh mesh;  ///< leaflets at end-diastole
  TetMesh linear;  ///< the corner (linear) mesh, for export
  std::vector<ModelChorda> chordae;
  /// Nodes whose motion is prescribed: the annulus (v = 0) on every layer, and for quadratic
  /// meshes the mid-edge nodes between them.
  std::vector<int> annulus_nodes;
  /// Triangles of the ventricular surface (corner nodes), oriented towards the ventricle: where
  /// the pressure acts.
  std::vector<Eigen::Vector3i> ventricular_faces;
  /// Papillary tips at end-diastole, mm.
  Eigen::Vector3d papillary_ed[2];
  /// Worst element shape: 6 sqrt(2) V / (longest edge)^3 (1 for a regular tetrahedron), and
  /// where it is. Slivers near the commissures (see docs/forward-status.md) show up here.
  double min_quality = 0.0;
  int worst_element = -1;

  /// Corner node of grid point (u, v) on layer l (0 = atrial surface, layers = ventricular):
  /// (l * vres + v) * ures + u, u wrapping around.
  int node(int u, int v, int layer) const;
};

/// Builds the model from the end-diastolic frame of a sequence. Throws mvtwin::Error naming the
/// problem (no end-diastolic frame, leaflets or papillary tips not observed there, invalid
/// options, an element inverted by the extrusion).
ValveModel build_valve_model(const ValveSequence& sequence, const ModelOptions& options = {});

}  // namespace mvtwin::forward
