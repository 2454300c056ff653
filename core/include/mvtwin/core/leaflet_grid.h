#pragma once
#include <Eigen/Core>

#include "mvtwin/core/tet_mesh.h"
#include "mvtwin/core/triangle_mesh.h"

namespace mvtwin {

/// The atrial (LA) surface of both leaflets sampled on the anatomical (u,v) grid of
/// Mansi et al. 2012 (Sec. 2.1), the grid that gives point correspondence across frames and
/// patients.
///
/// Convention (docs/valve-model.md):
///  - u = 0..ures-1 runs once around the annulus and wraps (column ures == column 0). u = 0 is
///    the anterolateral commissure (the annulus point Omega); u increases over the anterior
///    leaflet to the posteromedial commissure at u = ures/2, then over the posterior leaflet
///    back to u = 0. Seen from the atrium with the anterior leaflet on top, u runs clockwise.
///  - v = 0 is the annulus, v = vres-1 the free edge.
///  - Columns u in [0, ures/2] belong to the anterior leaflet, [ures/2, ures] to the posterior
///    one (the commissure columns are shared). Within each leaflet, u is spaced evenly in
///    annulus arc length, so the grid point (u, v) corresponds to the continuous coordinates
///    (u/ures, v/(vres-1)) at every resolution.
class LeafletGrid {
 public:
  using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

  LeafletGrid() = default;
  /// `points` holds ures*vres rows, row v*ures+u. Throws mvtwin::Error for a bad size or
  /// resolution (ures even and >= 8, vres >= 3).
  LeafletGrid(int ures, int vres, Points points);

  int ures() const { return ures_; }
  int vres() const { return vres_; }
  const Points& points() const { return points_; }
  Points& points() { return points_; }

  /// Grid point (u wraps around, v in [0, vres-1]) in mm.
  Eigen::Vector3d at(int u, int v) const;
  /// Smooth (bicubic Catmull-Rom) sample at continuous coordinates: s in [0,1) around the
  /// annulus (periodic), t in [0,1] from annulus to free edge.
  Eigen::Vector3d sample(double s, double t) const;
  /// The same surface on another grid; point correspondence is kept and grid points that
  /// coincide with old ones are reproduced exactly.
  LeafletGrid resampled(int ures, int vres) const;

  /// The grid as a triangle surface (2 triangles per quad, u wraps), normals towards the
  /// ventricle for a valve whose u runs clockwise seen from the atrium.
  TriangleMesh triangulate() const;
  /// Leaflet of each triangle of triangulate(), by the u of its quad.
  Eigen::VectorXi triangle_tags() const;
  /// Leaflet of grid column u: anterior for u in [0, ures/2), posterior otherwise.
  LeafletTag column_tag(int u) const;

  /// Arc length in mm along column u from the annulus to the free edge.
  double radial_length(int u) const;
  /// Radial length at a continuous u coordinate s in [0,1), measured on a fine resampling.
  double radial_length_at(double s) const;

 private:
  int ures_ = 0;
  int vres_ = 0;
  Points points_;
};

}  // namespace mvtwin
