#pragma once
#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/valve_parameters.h"
#include "mvtwin/core/valve_sequence.h"
#include "mvtwin/forward/solid_mesh.h"

namespace mvtwin::forward {

/// How the finite-element model of a valve is built (Mansi et al. 2012, Sec. 2.2).
struct ModelOptions {
  /// Grid of the model (the sequence is resampled to it; correspondence is kept).
  int ures = 30;
  int vres = 30;
  /// Element layers through the thickness.
  int layers = 1;
  /// Quadratic tetrahedra do not lock in bending at nu = 0.488; linear ones do (Mansi et al. 2012,
  /// Sec. 2.3).
  TetOrder order = TetOrder::kQuadratic;
  /// Quadratic elements follow the curved leaflet (mid-edge nodes on the surface,
  /// isoparametric) instead of faceting it with straight edges.
  bool curved = true;
  /// Marginal chordae evenly on the free edge (the paper: 28; sensitivity: 56, 20, 16, 12).
  int marginal_chordae = 28;
  /// Leaflet thickness in mm (Mansi et al. 2012, after Votta 2008 / Kunzelman 2007).
  double al_thickness_mm = 1.32;
  double pl_thickness_mm = 1.26;
  /// Noisy input surfaces (detection noise of 0.3-1 mm on every grid point) make degenerate
  /// elements. When the end-diastolic grid's roughness (grid_roughness: an estimate of the
  /// noise SD) exceeds this, it is smoothed (Taubin passes on every row but the annulus) until
  /// it is below a tenth of it, at most max_smoothing_passes passes (measured: 0.3-1 mm noise
  /// then builds elements of quality >= 0.005, within 0.6 mm of the clean surface). Clean grids are
  /// left as they are. 0 switches smoothing off.
  double smoothing_roughness_mm = 0.1;
  int max_smoothing_passes = 50;
  /// Local refinement (issue 39, item 1: a device's grasp is under-resolved at the paper's
  /// grid): inside each region the surface lattice and the free edge's points are
  /// `refine_factor` times denser (1: none). A region is a stretch of one leaflet around grid
  /// position s (0-1 around the annulus, as ClipOptions' sites), half_width_mm to either side
  /// along the annulus and from_edge_mm deep from the free edge (unrolled leaflet plane, mm).
  struct RefineRegion {
    double s = 0, half_width_mm = 0, from_edge_mm = 0;
  };
  std::vector<RefineRegion> refine_regions;
  int refine_factor = 1;

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
  double s = 0, t = 0;  ///< insertion site in grid coordinates (around, annulus to free edge)
  /// Insertion-point-to-tip distance at end-diastole, mm (rest length = this x factor).
  double ed_length = 0.0;
};

/// The finite-element model of a valve at end-diastole.
///
/// The leaflets are meshed on their own, not on the image grid: the atrial surface is
/// triangulated in the unrolled plane (annulus arc length, depth along the leaflet in mm) by a
/// Delaunay triangulation of a lattice clipped to the free edge, so that steep free edges (the
/// commissural notches, posterior clefts) get well-shaped elements, and each triangle is
/// extruded through the thickness into prisms split into 3 tetrahedra. The annulus row keeps
/// the grid's columns u = 0..ures-1. `vres` sets the depth spacing: mean leaflet length /
/// (vres - 1).
struct ValveModel {
  ModelOptions options;
  SolidMesh mesh;  ///< leaflets at end-diastole
  TetMesh linear;  ///< the corner (linear) mesh, for export
  std::vector<ModelChorda> chordae;
  /// Corner nodes per layer; corner node of surface node i on layer l is l * surface_nodes + i.
  int surface_nodes = 0;
  /// Grid coordinates of each surface node: s in [0,1) around the annulus (the image grid's u /
  /// ures), t in [0,1] from annulus to free edge.
  Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> surface_st;
  /// Each surface node in the unrolled plane: annulus arc length from u = 0 and depth along the
  /// leaflet from the annulus, mm; `perimeter` is the annulus length (the plane's period).
  Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> surface_plane;
  double perimeter = 0.0;
  /// Triangles of the atrial surface (surface node indices), normals towards the ventricle.
  Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor> surface_triangles;
  /// Surface node of annulus column u (u = 0..ures-1, t = 0).
  std::vector<int> annulus_column;
  /// Nodes whose motion is prescribed: the annulus (t = 0) on every layer, and for quadratic
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
  /// Roughness of the end-diastolic grid as given, mm, and the smoothing passes it received.
  double input_roughness_mm = 0.0;
  int smoothing_passes = 0;
  /// Quadratic elements kept straight-sided because curving them would distort them (counted
  /// per pass of the check; 0 normally).
  int straight_elements = 0;

  /// Corner node of surface node i on layer l (0 = atrial surface, layers = ventricular).
  int node(int i, int layer) const { return layer * surface_nodes + i; }
};

/// Samples the model's atrial surface on a (u,v) grid: for each grid point, the surface triangle
/// that holds it and its barycentric weights in the unrolled plane.
struct AtrialSampler {
  int ures = 0, vres = 0;
  std::vector<std::array<int, 3>> nodes;  ///< corner nodes (layer 0)
  /// Mid-edge nodes of the triangle's edges 01, 12, 20 (quadratic meshes; -1 for linear ones):
  /// the surface is then sampled with the 6-node triangle's shape functions, so that a
  /// deformed (curved) quadratic surface is sampled as the elements represent it.
  std::vector<std::array<int, 3>> mids;
  std::vector<Eigen::Vector3d> weights;  ///< barycentric coordinates in the unrolled plane
};
AtrialSampler make_atrial_sampler(const ValveModel& model, int ures, int vres);
/// The atrial surface at positions x (all nodes, flattened, mm) as a grid.
LeafletGrid sample_atrial(const AtrialSampler& sampler, const Eigen::VectorXd& x);
/// The same sampler moved to the ventricular surface (the last layer's nodes under the same
/// grid points): sample_atrial with it gives the leaflets' ventricular side on the grid.
AtrialSampler ventricular_sampler(const ValveModel& model, const AtrialSampler& atrial);

/// Roughness of a leaflet grid, mm: the RMS of fourth differences along u and v over the
/// rows beyond the annulus, scaled so that white noise of SD sigma per coordinate scores
/// sigma (smooth curvature scores ~0.01 mm).
double grid_roughness(const LeafletGrid& grid);
/// Taubin (lambda/mu) smoothing passes over every row but the annulus (v = 0), periodic in u;
/// the free-edge row is smoothed along the edge only.
void smooth_grid(LeafletGrid* grid, int passes);

/// Builds the model from the end-diastolic frame of a sequence. Throws mvtwin::Error naming the
/// problem (no end-diastolic frame, leaflets or papillary tips not observed there, invalid
/// options, an element inverted by the extrusion).
ValveModel build_valve_model(const ValveSequence& sequence, const ModelOptions& options = {});

}  // namespace mvtwin::forward
