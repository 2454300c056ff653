#include "mvtwin/core/closure_measures.h"
#include "mvtwin/core/point_to_mesh_distance.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Geometry>

#include "mvtwin/core/annulus_plane.h"
#include "mvtwin/core/error.h"

namespace mvtwin {
namespace {

// Even-odd point-in-polygon test.
bool inside_polygon(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& q) {
  bool in = false;
  for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const Eigen::Vector2d& a = poly[i];
    const Eigen::Vector2d& b = poly[j];
    if ((a.y() > q.y()) != (b.y() > q.y()) &&
        q.x() < (b.x() - a.x()) * (q.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      in = !in;
    }
  }
  return in;
}

}  // namespace

ClosureMeasures measure_closure(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& annulus,
    const TriangleMesh& leaflets, double res, double min_component_mm2) {
  if (!(res > 0.01 && res <= 5.0))
    throw Error("closure measures: resolution must be in (0.01, 5] mm");
  if (leaflets.F.rows() == 0) throw Error("closure measures: empty leaflet surface");
  if (annulus.rows() < 3 || !annulus.allFinite())
    throw Error("closure measures: the annulus needs at least 3 finite points");
  if (!leaflets.V.allFinite()) throw Error("closure measures: non-finite leaflet coordinates");
  const AnnulusPlane plane = least_squares_plane(annulus);
  Eigen::Vector3d e1 = annulus.row(0).transpose() - plane.point;
  e1 -= plane.normal * plane.normal.dot(e1);
  if (!(e1.norm() > 1e-9)) throw Error("closure measures: degenerate annulus");
  e1.normalize();
  const Eigen::Vector3d e2 = plane.normal.cross(e1);
  auto project = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d d = p - plane.point;
    return Eigen::Vector2d(d.dot(e1), d.dot(e2));
  };
  std::vector<Eigen::Vector2d> poly;
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e300), hi = -lo;
  for (Eigen::Index i = 0; i < annulus.rows(); ++i) {
    poly.push_back(project(annulus.row(i).transpose()));
    lo = lo.cwiseMin(poly.back());
    hi = hi.cwiseMax(poly.back());
  }
  const int nx = static_cast<int>(std::ceil((hi.x() - lo.x()) / res)) + 1;
  const int ny = static_cast<int>(std::ceil((hi.y() - lo.y()) / res)) + 1;
  if (static_cast<double>(nx) * ny > 4e7)
    throw Error("closure measures: annulus too large for the resolution");
  auto centre = [&](int i, int j) {
    return Eigen::Vector2d(lo.x() + (i + 0.5) * res, lo.y() + (j + 0.5) * res);
  };
  // 0 outside the opening, 1 open, 2 covered by a leaflet.
  std::vector<unsigned char> px(static_cast<size_t>(nx) * ny, 0);
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i)
      px[static_cast<size_t>(j) * nx + i] = inside_polygon(poly, centre(i, j));
  }
  for (Eigen::Index f = 0; f < leaflets.F.rows(); ++f) {
    const Eigen::Vector2d a = project(leaflets.V.row(leaflets.F(f, 0)).transpose()),
                          b = project(leaflets.V.row(leaflets.F(f, 1)).transpose()),
                          c = project(leaflets.V.row(leaflets.F(f, 2)).transpose());
    const double det = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
    if (std::abs(det) < 1e-14) continue;  // seen edge-on: covers nothing
    const Eigen::Vector2d tlo = a.cwiseMin(b).cwiseMin(c), thi = a.cwiseMax(b).cwiseMax(c);
    const int i0 = std::max(0, static_cast<int>(std::floor((tlo.x() - lo.x()) / res)));
    const int i1 = std::min(nx - 1, static_cast<int>(std::ceil((thi.x() - lo.x()) / res)));
    const int j0 = std::max(0, static_cast<int>(std::floor((tlo.y() - lo.y()) / res)));
    const int j1 = std::min(ny - 1, static_cast<int>(std::ceil((thi.y() - lo.y()) / res)));
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) {
        unsigned char& p = px[static_cast<size_t>(j) * nx + i];
        if (p != 1) continue;
        const Eigen::Vector2d r = centre(i, j) - a;
        const double u = (r.x() * (c - a).y() - r.y() * (c - a).x()) / det;
        const double v = ((b - a).x() * r.y() - (b - a).y() * r.x()) / det;
        if (u >= 0 && v >= 0 && u + v <= 1) p = 2;
      }
    }
  }
  ClosureMeasures m;
  m.resolution_mm = res;
  const double pixel = res * res;
  for (unsigned char p : px) m.annulus_area_mm2 += p ? pixel : 0.0;
  // Connected openings (4-neighbourhood), small ones dropped as rasterization noise.
  std::vector<int> stack;
  for (size_t s = 0; s < px.size(); ++s) {
    if (px[s] != 1) continue;
    int count = 0;
    stack.push_back(static_cast<int>(s));
    px[s] = 3;
    while (!stack.empty()) {
      const int k = stack.back();
      stack.pop_back();
      ++count;
      const int i = k % nx, j = k / nx;
      const int nb[4][2] = {{i - 1, j}, {i + 1, j}, {i, j - 1}, {i, j + 1}};
      for (const auto& q : nb) {
        if (q[0] < 0 || q[1] < 0 || q[0] >= nx || q[1] >= ny) continue;
        const size_t id = static_cast<size_t>(q[1]) * nx + q[0];
        if (px[id] == 1) {
          px[id] = 3;
          stack.push_back(static_cast<int>(id));
        }
      }
    }
    if (count * pixel >= min_component_mm2) {
      m.orifice_area_mm2 += count * pixel;
      ++m.orifice_components;
      m.component_areas_mm2.push_back(count * pixel);
    }
  }
  std::sort(m.component_areas_mm2.rbegin(), m.component_areas_mm2.rend());
  return m;
}

Coaptation measure_coaptation(const LeafletGrid& g, double contact_mm) {
  if (!(contact_mm > 0)) throw Error("coaptation: contact distance must be positive");
  if (!g.points().allFinite()) throw Error("coaptation: non-finite surface coordinates");
  const TriangleMesh all = g.triangulate();
  const Eigen::VectorXi tags = g.triangle_tags();
  TriangleMesh posterior;
  posterior.V = all.V;
  int n = 0;
  for (Eigen::Index k = 0; k < tags.size(); ++k)
    n += tags[k] == static_cast<int>(LeafletTag::kPosterior);
  posterior.F.resize(n, 3);
  n = 0;
  for (Eigen::Index k = 0; k < tags.size(); ++k)
    if (tags[k] == static_cast<int>(LeafletTag::kPosterior)) posterior.F.row(n++) = all.F.row(k);
  const int U = g.ures(), V = g.vres(), half = U / 2;
  const int u0 = static_cast<int>(std::ceil(0.15 * half)),
            u1 = static_cast<int>(std::floor(0.85 * half));
  std::vector<double> lengths;
  Coaptation c;
  int looked = 0;
  for (int u = u0; u <= u1; ++u) {
    Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> col(V, 3);
    for (int v = 0; v < V; ++v) col.row(v) = g.at(u, v).transpose();
    const std::vector<double> d = point_to_mesh_distances(col, posterior);
    double len = 0;
    for (int v = 0; v + 1 < V; ++v) {
      const double seg = (col.row(v + 1) - col.row(v)).norm();
      const bool a = d[v] <= contact_mm, b = d[v + 1] <= contact_mm;
      if (a && b) {
        len += seg;
      } else if (a != b) {
        // The part of the segment within reach, by linear interpolation of the distance.
        const double da = d[v] - contact_mm, db = d[v + 1] - contact_mm;
        const double f = da / (da - db);  // where the distance crosses contact_mm
        len += seg * (a ? f : 1.0 - f);
      }
    }
    ++looked;
    if (len > 0) lengths.push_back(len);
  }
  c.coapting_fraction = looked > 0 ? static_cast<double>(lengths.size()) / looked : 0.0;
  if (!lengths.empty()) {
    std::sort(lengths.begin(), lengths.end());
    c.length_mm = lengths[lengths.size() / 2];
    c.max_mm = lengths.back();
  }
  return c;
}

ClosureMeasures measure_closure(const ValveFrame& frame, double resolution_mm) {
  if (!frame.la_surface) throw Error("closure measures: the frame has no leaflet surface");
  return measure_closure(frame.annulus, frame.la_surface->triangulate(), resolution_mm);
}

}  // namespace mvtwin
