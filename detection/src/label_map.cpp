#include "mvtwin/detection/label_map.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Dense>

#include "mvtwin/core/annulus_plane.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/rng.h"

namespace mvtwin::detection {
namespace {

using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// Unit vertex normals of the grid's triangulation (towards the ventricle), area-weighted.
Points vertex_normals(const TriangleMesh& m) {
  Points n = Points::Zero(m.V.rows(), 3);
  for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
    const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
    const Eigen::Vector3d w = (b - a).cross(c - a);
    for (int k = 0; k < 3; ++k) n.row(m.F(f, k)) += w.transpose();
  }
  for (Eigen::Index i = 0; i < n.rows(); ++i) n.row(i).normalize();
  return n;
}

/// Centres of the papillary spheres: each tip moved by the radius away from the atrium, so that
/// the tip is the sphere's atrial-most point. Empty without both tips or a papillary label.
std::vector<Eigen::Vector3d> papillary_centres(const ValveFrame& frame, const LabelMapOptions& o) {
  if (o.labels.papillary == 0 || !frame.observed(Landmark::kAnterolateralPapillaryTip) ||
      !frame.observed(Landmark::kPosteromedialPapillaryTip))
    return {};
  const Eigen::Vector3d atrial = atrial_direction(frame.annulus);
  return {frame.landmark(Landmark::kAnterolateralPapillaryTip) - o.papillary_radius_mm * atrial,
          frame.landmark(Landmark::kPosteromedialPapillaryTip) - o.papillary_radius_mm * atrial};
}

}  // namespace

bool LabelMapOptions::is_valid(std::string* error) const {
  if (!labels.is_valid(error)) return false;
  if (!(voxel_mm >= 0.1 && voxel_mm <= 3.0)) {
    *error = "voxel size must be in [0.1, 3] mm";
    return false;
  }
  if (!(al_thickness_mm > 0 && pl_thickness_mm > 0 && annulus_radius_mm > 0 &&
        papillary_radius_mm > 0 && margin_mm >= 0)) {
    *error = "thicknesses, radii and the margin must be positive";
    return false;
  }
  if (!(boundary_noise >= 0 && boundary_noise <= 1)) {
    *error = "boundary noise must be in [0, 1]";
    return false;
  }
  if (supersample < 1 || supersample > 8) {
    *error = "supersample must be in [1, 8]";
    return false;
  }
  if (direction && !(direction->transpose() * *direction).isIdentity(1e-6)) {
    *error = "voxel axes must be orthonormal";
    return false;
  }
  return true;
}

ImageVolume label_map_geometry(const ValveFrame& frame, const LabelMapOptions& o) {
  std::string err;
  if (!o.is_valid(&err)) throw Error("label map: " + err);
  if (!frame.la_surface) throw Error("label map: the frame has no leaflet surface");
  const LeafletGrid& g = *frame.la_surface;
  const TriangleMesh top = g.triangulate();
  const Points nrm = vertex_normals(top);
  const double thick = std::max(o.al_thickness_mm, o.pl_thickness_mm);
  ImageVolume im;
  im.direction = o.direction ? *o.direction : Eigen::Matrix3d::Identity();
  im.spacing = Eigen::Vector3d::Constant(o.voxel_mm);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  auto grow = [&](const Eigen::Vector3d& p, double r) {
    const Eigen::Vector3d q = im.direction.transpose() * p;
    lo = lo.cwiseMin(q - Eigen::Vector3d::Constant(r));
    hi = hi.cwiseMax(q + Eigen::Vector3d::Constant(r));
  };
  for (Eigen::Index i = 0; i < top.V.rows(); ++i) {
    grow(top.V.row(i).transpose(), 0);
    grow((top.V.row(i) + thick * nrm.row(i)).transpose(), 0);
  }
  if (o.labels.annulus != 0)
    for (Eigen::Index u = 0; u < frame.annulus.rows(); ++u)
      grow(frame.annulus.row(u).transpose(), o.annulus_radius_mm);
  for (const Eigen::Vector3d& c : papillary_centres(frame, o)) grow(c, o.papillary_radius_mm);
  lo -= Eigen::Vector3d::Constant(o.margin_mm);
  hi += Eigen::Vector3d::Constant(o.margin_mm);
  lo = (lo / o.voxel_mm).array().floor().matrix() * o.voxel_mm;  // on the lattice
  for (int k = 0; k < 3; ++k) {
    im.size[k] = static_cast<int>(std::ceil((hi[k] - lo[k]) / o.voxel_mm)) + 1;
    if (im.size[k] > 2000) throw Error("label map: the valve spans more than 2000 voxels");
  }
  im.origin = im.direction * lo;
  return im;
}

ImageVolume union_geometry(const std::vector<ImageVolume>& boxes) {
  if (boxes.empty()) throw Error("label map: no geometry to join");
  ImageVolume out = boxes.front();
  out.data.clear();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const ImageVolume& b : boxes) {
    if (!b.spacing.isApprox(out.spacing) || !b.direction.isApprox(out.direction))
      throw Error("label map: frames of a sequence need the same voxel size and axes");
    const Eigen::Vector3d q = out.direction.transpose() * b.origin;
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(
        q + b.spacing.cwiseProduct(Eigen::Vector3d(b.size[0] - 1, b.size[1] - 1, b.size[2] - 1)));
  }
  for (int k = 0; k < 3; ++k)
    out.size[k] = static_cast<int>(std::lround((hi[k] - lo[k]) / out.spacing[k])) + 1;
  out.origin = out.direction * lo;
  return out;
}

ImageVolume valve_label_map(const ValveFrame& frame, const LabelMapOptions& o) {
  std::string err;
  if (!o.is_valid(&err)) throw Error("label map: " + err);
  if (!frame.la_surface) throw Error("label map: the frame has no leaflet surface");
  // A fine copy of the grid, so that the rasterized slab follows the smooth surface.
  const LeafletGrid& g0 = *frame.la_surface;
  const LeafletGrid g = g0.resampled(std::max(g0.ures(), 2 * ((3 * g0.ures() / 2 + 1) / 2)),
                                     std::max(g0.vres(), 3 * g0.vres() / 2));
  const int U = g.ures(), V = g.vres();
  const TriangleMesh top = g.triangulate();
  const Points nrm = vertex_normals(top);
  Points bottom(top.V.rows(), 3);
  for (int v = 0; v < V; ++v) {
    for (int u = 0; u < U; ++u) {
      const int i = v * U + u;
      const double t =
          g.column_tag(u) == LeafletTag::kAnterior ? o.al_thickness_mm : o.pl_thickness_mm;
      bottom.row(i) = top.V.row(i) + t * nrm.row(i);
    }
  }
  const bool with_annulus = o.labels.annulus != 0;
  const std::vector<Eigen::Vector3d> papillary_centre = papillary_centres(frame, o);

  // Geometry: the given one, or an axis-aligned box (in the voxel axes) around everything drawn.
  ImageVolume im = o.geometry ? *o.geometry : label_map_geometry(frame, o);
  im.data.clear();
  const int S = o.supersample;
  const std::array<long, 3> ns = {static_cast<long>(im.size[0]) * S,
                                  static_cast<long>(im.size[1]) * S,
                                  static_cast<long>(im.size[2]) * S};
  // Sub-sample m along an axis sits at index coordinate (m + 0.5) / S - 0.5.
  std::vector<std::uint8_t> sub(static_cast<std::size_t>(ns[0] * ns[1] * ns[2]), 0);
  auto sub_at = [&](long a, long b, long c) -> std::uint8_t& {
    return sub[static_cast<std::size_t>(a + ns[0] * (b + ns[1] * c))];
  };
  // The sub-samples whose index coordinates lie in [bl, bh], clamped to the image.
  auto sub_range = [&](const Eigen::Vector3d& bl, const Eigen::Vector3d& bh, long* m0, long* m1) {
    for (int k = 0; k < 3; ++k) {
      m0[k] = std::max(0L, static_cast<long>(std::ceil((bl[k] + 0.5) * S - 0.5)));
      m1[k] = std::min(ns[k] - 1, static_cast<long>(std::floor((bh[k] + 0.5) * S - 0.5)));
    }
  };
  const Eigen::Matrix3d to_index = (im.direction * im.spacing.asDiagonal()).inverse();
  auto idx = [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return to_index * (p - im.origin);
  };

  // Leaflets: every prism (a triangle of the top surface and its extrusion) as 3 tetrahedra,
  // split by global vertex order so that neighbouring prisms share their quad faces' diagonals.
  const Eigen::VectorXi tags = g.triangle_tags();
  auto raster_tet = [&](const Eigen::Vector3d& A, const Eigen::Vector3d& B,
                        const Eigen::Vector3d& C, const Eigen::Vector3d& D, std::uint8_t value) {
    Eigen::Matrix3d M;
    M << B - A, C - A, D - A;
    if (std::abs(M.determinant()) < 1e-12) return;
    const Eigen::Matrix3d Minv = M.inverse();
    Eigen::Vector3d bl = A.cwiseMin(B).cwiseMin(C).cwiseMin(D),
                    bh = A.cwiseMax(B).cwiseMax(C).cwiseMax(D);
    long m0[3], m1[3];
    sub_range(bl, bh, m0, m1);
    for (long c = m0[2]; c <= m1[2]; ++c)
      for (long b = m0[1]; b <= m1[1]; ++b)
        for (long a = m0[0]; a <= m1[0]; ++a) {
          const Eigen::Vector3d q((a + 0.5) / S - 0.5, (b + 0.5) / S - 0.5, (c + 0.5) / S - 0.5);
          const Eigen::Vector3d w = Minv * (q - A);
          if (w.minCoeff() >= -1e-12 && w.sum() <= 1.0 + 1e-12) sub_at(a, b, c) = value;
        }
  };
  for (Eigen::Index f = 0; f < top.F.rows(); ++f) {
    std::array<int, 3> v = {top.F(f, 0), top.F(f, 1), top.F(f, 2)};
    std::sort(v.begin(), v.end());
    const Eigen::Vector3d a = idx(top.V.row(v[0]).transpose()),
                          b = idx(top.V.row(v[1]).transpose()),
                          c = idx(top.V.row(v[2]).transpose());
    const Eigen::Vector3d a2 = idx(bottom.row(v[0]).transpose()),
                          b2 = idx(bottom.row(v[1]).transpose()),
                          c2 = idx(bottom.row(v[2]).transpose());
    const std::uint8_t value = tags[f] == static_cast<int>(LeafletTag::kAnterior) ? 1 : 2;
    raster_tet(a, b, c, c2, value);
    raster_tet(a, b, b2, c2, value);
    raster_tet(a, a2, b2, c2, value);
  }

  // Annulus tube and papillary spheres, by distance (they override the leaflets).
  const Points ring = with_annulus ? resample_closed_curve(frame.annulus, 960) : Points(0, 3);
  // The tube test against the ring samples near piece `from` (the ring is sampled every
  // ~0.15 mm, finer than any sub-sample).
  auto near_ring = [&](Eigen::Index from, const Eigen::Vector3d& p) {
    const Eigen::Index n = ring.rows();
    for (Eigen::Index j = from - 24; j <= from + 48; ++j)
      if ((ring.row((j + n) % n).transpose() - p).squaredNorm() <=
          o.annulus_radius_mm * o.annulus_radius_mm)
        return true;
    return false;
  };
  auto paint_shape = [&](const Eigen::Vector3d& lo_p, const Eigen::Vector3d& hi_p,
                         std::uint8_t value, auto&& inside) {
    Eigen::Vector3d bl = Eigen::Vector3d::Constant(1e300), bh = -bl;
    for (int corner = 0; corner < 8; ++corner) {
      const Eigen::Vector3d p((corner & 1) ? hi_p.x() : lo_p.x(),
                              (corner & 2) ? hi_p.y() : lo_p.y(),
                              (corner & 4) ? hi_p.z() : lo_p.z());
      const Eigen::Vector3d q = idx(p);
      bl = bl.cwiseMin(q);
      bh = bh.cwiseMax(q);
    }
    long m0[3], m1[3];
    sub_range(bl, bh, m0, m1);
    const Eigen::Matrix3d axes = im.direction * im.spacing.asDiagonal();
    for (long c = m0[2]; c <= m1[2]; ++c)
      for (long b = m0[1]; b <= m1[1]; ++b)
        for (long a = m0[0]; a <= m1[0]; ++a) {
          const Eigen::Vector3d p =
              im.origin +
              axes * Eigen::Vector3d((a + 0.5) / S - 0.5, (b + 0.5) / S - 0.5, (c + 0.5) / S - 0.5);
          if (inside(p)) sub_at(a, b, c) = value;
        }
  };
  if (with_annulus) {
    // Piece by piece along the ring, so that each box stays small.
    const double r = o.annulus_radius_mm;
    for (Eigen::Index i = 0; i < ring.rows(); i += 24) {
      Eigen::Vector3d bl = Eigen::Vector3d::Constant(1e300), bh = -bl;
      for (Eigen::Index j = i; j <= i + 24; ++j) {
        bl = bl.cwiseMin(ring.row(j % ring.rows()).transpose());
        bh = bh.cwiseMax(ring.row(j % ring.rows()).transpose());
      }
      paint_shape(bl - Eigen::Vector3d::Constant(r), bh + Eigen::Vector3d::Constant(r), 3,
                  [&](const Eigen::Vector3d& p) { return near_ring(i, p); });
    }
  }
  {
    const double r = o.papillary_radius_mm;
    for (const auto& c : papillary_centre) {
      paint_shape(c - Eigen::Vector3d::Constant(r), c + Eigen::Vector3d::Constant(r), 4,
                  [&](const Eigen::Vector3d& p) { return (p - c).squaredNorm() <= r * r; });
    }
  }

  // Partial-volume fractions, thresholded at 1/2 with noise on the boundary voxels.
  Rng rng(o.seed);
  const int values[5] = {0, o.labels.anterior, o.labels.posterior, o.labels.annulus,
                         o.labels.papillary};
  im.data.assign(im.num_voxels(), 0.0f);
  const int S3 = S * S * S;
  for (int k = 0; k < im.size[2]; ++k)
    for (int j = 0; j < im.size[1]; ++j)
      for (int i = 0; i < im.size[0]; ++i) {
        int count[5] = {0, 0, 0, 0, 0};
        for (int c = 0; c < S; ++c)
          for (int b = 0; b < S; ++b)
            for (int a = 0; a < S; ++a)
              ++count[sub_at(static_cast<long>(i) * S + a, static_cast<long>(j) * S + b,
                             static_cast<long>(k) * S + c)];
        if (count[0] == S3) continue;
        double f = 1.0 - static_cast<double>(count[0]) / S3;
        if (count[0] > 0 && o.boundary_noise > 0) f += rng.normal(0.0, o.boundary_noise);
        if (f < 0.5) continue;
        int best = 1;
        for (int l = 2; l < 5; ++l)
          if (count[l] > count[best]) best = l;
        im.data[static_cast<std::size_t>(i) + static_cast<std::size_t>(im.size[0]) *
                                                  (j + static_cast<std::size_t>(im.size[1]) * k)] =
            static_cast<float>(values[best]);
      }
  return im;
}

}  // namespace mvtwin::detection
