#pragma once
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/image_volume.h"
#include "mvtwin/core/point_to_mesh_distance.h"
#include "mvtwin/core/valve_sequence.h"
#include "mvtwin/detection/segmentation_labels.h"

namespace mvtwin::detection {

struct SegmentationFitOptions {
  SegmentationLabels labels;
  /// Output grid (docs/valve-model.md).
  int ures = 30;
  int vres = 30;
  /// Direction into the left atrium in image space. When empty it is inferred: the leaflets
  /// lie on the ventricular side of the annulus, open (hanging) or closed (tenting).
  std::optional<Eigen::Vector3d> atrial_direction;
  /// Use the annulus label for the annulus when there is one (the leaflet rim is then fitted
  /// too, and both are reported); false: always the rim.
  bool use_annulus_label = true;
  /// A secondary connected component of a leaflet label with at least this fraction of the
  /// largest one's voxels is an error (smaller ones are dropped, with a note).
  double max_secondary_component = 0.1;

  bool is_valid(std::string* error) const;
};

/// One frame fitted to a label map, and how well it fits.
struct FrameFit {
  /// Annulus, LA surface on the (u,v) grid, commissures, posterior annulus mid-point, leaflet
  /// tips; the papillary tips when the map has a papillary label. Time 0 (the caller sets it).
  ValveFrame frame;
  /// "annulus label", "leaflet rim" or "leaflet mesh rim".
  std::string annulus_source;
  /// The file (and frame) it came from.
  std::string source;
  /// Fitted surface vertices -> boundary of the leaflet mask (voxel faces), mm.
  DistanceStats surface_to_mask;
  /// Atrial-facing boundary faces of the leaflet mask -> fitted surface, mm.
  DistanceStats mask_to_surface;
  /// Fitted annulus -> annulus voxel centres (when labelled), mm.
  std::optional<DistanceStats> annulus_to_label;
  /// The annulus from the leaflet rim against the one from the label (both fitted when the map
  /// has an annulus label), point to point on the grid, mm.
  std::optional<DistanceStats> rim_vs_label;
  /// The rim annulus -> the nearest annulus-label voxel (the rim lies at the label's inner
  /// edge, where the leaflet labels stop), mm.
  std::optional<DistanceStats> rim_to_label_voxels;
  /// The rim annulus itself (ures by 3) when both were fitted.
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> rim_annulus;
  /// Orifice seen from the atrium: annulus area not covered by leaflet, mm^2 (large when open).
  double orifice_area_mm2 = 0.0;
  int anterior_voxels = 0, posterior_voxels = 0, annulus_voxels = 0, papillary_voxels = 0;
  /// How choices were made (atrial side, commissures, dropped components) and warnings.
  std::vector<std::string> notes;
  std::vector<std::string> warnings;
};

/// Fits the anatomical valve model to one label map (an open or a closed frame). Throws
/// mvtwin::Error naming `source` and the problem: a leaflet label absent or too small, leaflets
/// that touch the image border, several large disconnected components, no commissures, a
/// column whose leaflet cannot be followed.
FrameFit fit_segmentation_frame(const ImageVolume& label_map, const std::string& source,
                                const SegmentationFitOptions& options = {});

}  // namespace mvtwin::detection

namespace mvtwin::detection {

/// Fits the valve model to leaflet surface meshes (STL, PLY, VTK from other tools): each mesh is
/// taken as its leaflet's atrial surface, or as a closed surface of the leaflet's volume (whose
/// atrial side is used). The meshes are rasterized at `voxel_mm` into a slab of half a leaflet's
/// thickness either side, fitted like a label map without an annulus label, and the grid is
/// then moved onto the meshes (closest points). Throws mvtwin::Error naming `source`.
FrameFit fit_surface_frame(const TriangleMesh& anterior, const TriangleMesh& posterior,
                           const std::string& source, const SegmentationFitOptions& options = {},
                           double voxel_mm = 0.4);

/// The grid's surface as two leaflet meshes (anterior, posterior), resampled to ures x vres
/// first: what a tool exporting leaflet surfaces gives, each mesh with its own copy of the
/// shared commissure columns and only the vertices it uses.
std::pair<TriangleMesh, TriangleMesh> leaflet_surface_meshes(const LeafletGrid& grid, int ures,
                                                             int vres);

/// Splits one mesh holding both leaflets into its two largest connected pieces, anterior first:
/// the anterior leaflet is the rounder piece, area / boundary length^2 (a tall shield on a third
/// of the annulus; the posterior one is a long low crescent). Throws mvtwin::Error naming
/// `source` when it is one connected piece.
std::pair<TriangleMesh, TriangleMesh> split_leaflet_meshes(const TriangleMesh& both,
                                                           const std::string& source);

}  // namespace mvtwin::detection
