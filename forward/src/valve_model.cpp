#include "mvtwin/forward/valve_model.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <set>

#include <Eigen/Geometry>

#include "mvtwin/core/error.h"
#include "mvtwin/forward/corotational_tet.h"
#include "mvtwin/forward/delaunay_2d.h"

namespace mvtwin::forward {
namespace {

using std::numbers::pi;

// Fibre angle from circumferential, by leaflet and position: circumferential everywhere except
// near the commissures of the anterior leaflet, where it turns gradually to radial
// (Mansi et al. 2012, Fig. 5, after May-Newman and Yin 1995).
double fibre_angle(bool anterior, double s_in_leaflet) {
  if (!anterior) return 0.0;
  const double from_commissure = std::min(s_in_leaflet, 1.0 - s_in_leaflet);
  const double w = std::max(0.0, 1.0 - from_commissure / 0.25);
  return 0.5 * pi * w * w;
}

}  // namespace

bool ModelOptions::is_valid(std::string* error) const {
  if (ures < 8 || ures % 2) {
    *error = "ures must be even and >= 8";
    return false;
  }
  if (vres < 4) {
    *error = "vres must be >= 4";
    return false;
  }
  if (layers < 1 || layers > 8) {
    *error = "layers must be in 1..8";
    return false;
  }
  if (marginal_chordae < 4 || marginal_chordae > 4 * ures) {
    *error = "marginal_chordae must be in 4..4*ures";
    return false;
  }
  if (!(smoothing_roughness_mm >= 0) || max_smoothing_passes < 0 || max_smoothing_passes > 1000) {
    *error = "smoothing_roughness_mm must be >= 0 and max_smoothing_passes in 0..1000";
    return false;
  }
  if (refine_factor < 1 || refine_factor > 6) {
    *error = "refine_factor must be in 1..6";
    return false;
  }
  for (const RefineRegion& r : refine_regions) {
    if (!(r.s >= 0 && r.s <= 1 && r.half_width_mm >= 0 && r.half_width_mm < 100 &&
          r.from_edge_mm >= 0 && r.from_edge_mm < 100)) {
      *error = "a refinement region needs s in [0, 1] and a half width and depth in [0, 100) mm";
      return false;
    }
  }
  if (!(al_thickness_mm > 0.1 && al_thickness_mm < 5 && pl_thickness_mm > 0.1 &&
        pl_thickness_mm < 5)) {
    *error = "leaflet thickness must be in (0.1, 5) mm";
    return false;
  }
  return true;
}

namespace {

/// The leaflet surface unrolled: xi = annulus arc length (mm, periodic with the perimeter),
/// depth = arc length along the leaflet from the annulus (mm), up to the free edge L(xi).
class Unrolled {
 public:
  explicit Unrolled(const LeafletGrid& g, int ures) : grid_(g) {
    const int n = 32 * ures;
    s_.resize(n + 1);
    xi_.resize(n + 1);
    length_.resize(n + 1);
    xi_[0] = 0.0;
    Eigen::Vector3d prev = g.sample(0.0, 0.0);
    for (int k = 0; k <= n; ++k) {
      s_[k] = static_cast<double>(k) / n;
      if (k > 0) {
        const Eigen::Vector3d p = g.sample(s_[k] < 1.0 ? s_[k] : 0.0, 0.0);
        xi_[k] = xi_[k - 1] + (p - prev).norm();
        prev = p;
      }
      length_[k] = k < n ? g.radial_length_at(s_[k]) : length_[0];
    }
    perimeter_ = xi_[n];
  }
  double perimeter() const { return perimeter_; }
  /// Around-coordinate s in [0,1) -> xi.
  double xi(double s) const { return interp(s_, xi_, wrap(s)); }
  /// xi -> s in [0,1).
  double s_of(double xi) const {
    xi = xi - perimeter_ * std::floor(xi / perimeter_);
    return interp(xi_, s_, xi);
  }
  /// Free-edge depth at xi.
  double free_edge(double xi) const { return interp(s_, length_, s_of(xi)); }
  /// Grid coordinates (s, t) of (xi, depth).
  Eigen::Vector2d st(double xi, double depth) const {
    const double s = s_of(xi);
    return {s, std::clamp(depth / interp(s_, length_, s), 0.0, 1.0)};
  }
  Eigen::Vector3d position(const Eigen::Vector2d& st) const { return grid_.sample(st[0], st[1]); }

 private:
  static double wrap(double s) { return s - std::floor(s); }
  static double interp(const std::vector<double>& x, const std::vector<double>& y, double q) {
    const auto it = std::upper_bound(x.begin(), x.end(), q);
    if (it == x.begin()) return y.front();
    if (it == x.end()) return y.back();
    const size_t k = static_cast<size_t>(it - x.begin());
    const double w = (q - x[k - 1]) / (x[k] - x[k - 1]);
    return y[k - 1] + w * (y[k] - y[k - 1]);
  }
  const LeafletGrid& grid_;
  std::vector<double> s_, xi_, length_;
  double perimeter_ = 0.0;
};

/// Deterministic sub-resolution jitter that breaks the co-circularity of lattice points.
double jitter(int i, int j) {
  const unsigned h = static_cast<unsigned>(i) * 73856093u ^ static_cast<unsigned>(j) * 19349663u;
  return (static_cast<double>(h % 1000u) / 1000.0 - 0.5);
}

struct SurfaceMesh {
  std::vector<Eigen::Vector2d> plane;  // (xi, depth) in mm
  std::vector<Eigen::Vector2d> st;
  std::vector<std::array<int, 3>> triangles;  // counter-clockwise in (xi, depth)
  std::vector<int> annulus_column;
  std::vector<char> free_edge;
};

/// Triangulates the unrolled leaflet: the annulus row at the grid's columns, a lattice of
/// spacing (perimeter/ures, depth step) inside, points every depth step along the free edge, and
/// a Delaunay triangulation (in coordinates scaled so that the lattice is square) clipped to the
/// leaflet.
SurfaceMesh mesh_surface(const Unrolled& un, int U, int V,
                         const std::vector<ModelOptions::RefineRegion>& regions, int factor) {
  const double P = un.perimeter(), hx = P / U;
  double mean_length = 0.0;
  for (int u = 0; u < U; ++u) mean_length += un.free_edge(un.xi(static_cast<double>(u) / U)) / U;
  // Depth step from vres, but elements no flatter than kMaxAnisotropy : 1 in the unrolled
  // plane: Delaunay triangles are shaped in the scaled plane, and any of them not aligned with
  // the axes becomes a sliver in 3D when the scale is large (measured: worst tetrahedron quality
  // 4e-4 at 6.6 : 1, ures = vres = 30).
  constexpr double kMaxAnisotropy = 2.5;
  const double hd = std::max(mean_length / (V - 1), hx / kMaxAnisotropy);
  const double scale = hx / hd;  // depth -> lattice units
  // Refinement regions in the unrolled plane: the site's arc length, its half width, and the
  // depth from the free edge. `grow` (mm along the annulus; the same in lattice units in depth)
  // widens them; only the first `count` zones are asked.
  struct Zone {
    double xi, half_width, from_edge;
  };
  std::vector<Zone> zones;
  if (factor > 1) {
    for (const auto& r : regions) zones.push_back({un.xi(r.s), r.half_width_mm, r.from_edge_mm});
  }
  auto in_zone = [&](double xi, double depth, double grow,
                     size_t count = std::numeric_limits<size_t>::max()) {
    for (size_t i = 0; i < std::min(count, zones.size()); ++i) {
      const Zone& z = zones[i];
      double dx = xi - z.xi;
      dx -= P * std::round(dx / P);
      if (std::abs(dx) <= z.half_width + grow &&
          depth >= un.free_edge(xi) - z.from_edge - grow * hd / hx)
        return true;
    }
    return false;
  };
  SurfaceMesh sm;
  // Whether a point of the scaled plane lies within `radius` of a free-edge point.
  std::vector<Eigen::Vector2d> edge;
  auto near_edge = [&](const Eigen::Vector2d& q, double radius) {
    for (const auto& e : edge) {
      Eigen::Vector2d diff = q - e;
      diff.x() -= P * std::round(diff.x() / P);
      if (diff.norm() < radius) return true;
    }
    return false;
  };
  auto add = [&](double xi, double depth, bool on_edge) {
    sm.plane.emplace_back(xi, depth);
    sm.free_edge.push_back(on_edge);
    return static_cast<int>(sm.plane.size()) - 1;
  };
  for (int u = 0; u < U; ++u) sm.annulus_column.push_back(add(un.xi(double(u) / U), 0.0, false));
  // Free edge: a point every lattice unit of the scaled curve.
  {
    const int fine = 64 * U;
    Eigen::Vector2d last(0.0, un.free_edge(0.0) * scale);
    edge.push_back(last);
    for (int k = 1; k < fine; ++k) {
      const double xi = P * k / fine;
      const Eigen::Vector2d q(xi, un.free_edge(xi) * scale);
      const double to_end = Eigen::Vector2d(P - xi, (un.free_edge(0.0) * scale - q.y())).norm();
      const double step = in_zone(xi, un.free_edge(xi), 0.0) ? hx / factor : hx;
      if ((q - last).norm() >= step && to_end >= 0.5 * step) {
        edge.push_back(q);
        last = q;
      }
    }
  }
  for (const auto& q : edge) add(q.x(), q.y() / scale, true);
  const int num_edge = static_cast<int>(edge.size());
  // Interior lattice, away from the free edge and the annulus.
  for (int u = 0; u < U; ++u) {
    for (int j = 1;; ++j) {
      const double xi = un.xi((u + 0.5 * (j % 2)) / U);
      const double d = j * hd;
      if (d > un.free_edge(xi) - 0.5 * hd) {
        if (d > 1.5 * mean_length) break;
        continue;
      }
      if (!near_edge(Eigen::Vector2d(xi, d * scale), 0.6 * hx) && !in_zone(xi, d, 0.5 * hx))
        add(xi + 1e-4 * hx * jitter(u, j), d + 1e-4 * hd * jitter(j, u), false);
    }
  }
  // Inside the refinement zones (and half a coarse step around them, where the coarse lattice
  // was left out), a lattice `factor` times finer, away from the free edge.
  if (!zones.empty()) {
    const double fx = hx / factor, fd = hd / factor;
    for (size_t zi = 0; zi < zones.size(); ++zi) {
      const Zone& z = zones[zi];
      const int kx = static_cast<int>(std::ceil((z.half_width + 0.5 * hx) / fx)) + 1;
      for (int j = 1;; ++j) {
        const double d = j * fd;
        if (d > 1.5 * mean_length) break;
        for (int k = -kx; k <= kx; ++k) {
          double xi = z.xi + (k + 0.5 * (j % 2)) * fx;
          xi -= P * std::floor(xi / P);
          if (!in_zone(xi, d, 0.5 * hx) || d > un.free_edge(xi) - 0.5 * fd) continue;
          // Once per point: the first zone that holds it places it.
          if (in_zone(xi, d, 0.5 * hx, zi)) continue;
          if (!near_edge(Eigen::Vector2d(xi, d * scale), 0.6 * fx))
            add(xi + 1e-4 * fx * jitter(k + 1000, j), d + 1e-4 * fd * jitter(j, k), false);
        }
      }
    }
  }
  // Periodic Delaunay (copies of the points near the seam on the other side) clipped to the
  // leaflet, then Laplacian smoothing of the interior points in the scaled plane and a second
  // triangulation of the smoothed points.
  const int n = static_cast<int>(sm.plane.size());
  auto triangulate = [&] {
    std::vector<Eigen::Vector2d> pts;
    std::vector<int> origin;
    for (int i = 0; i < n; ++i) {
      pts.emplace_back(sm.plane[i].x(), sm.plane[i].y() * scale);
      origin.push_back(i);
    }
    for (int i = 0; i < n; ++i) {
      if (sm.plane[i].x() < 4 * hx) {
        pts.emplace_back(sm.plane[i].x() + P, sm.plane[i].y() * scale);
        origin.push_back(i);
      }
      if (sm.plane[i].x() > P - 4 * hx) {
        pts.emplace_back(sm.plane[i].x() - P, sm.plane[i].y() * scale);
        origin.push_back(i);
      }
    }
    sm.triangles.clear();
    for (const auto& t : delaunay_2d(pts)) {
      const Eigen::Vector2d c = (pts[t[0]] + pts[t[1]] + pts[t[2]]) / 3.0;
      if (c.x() < 0.0 || c.x() >= P) continue;
      // Inside the leaflet: the centroid and the edge midpoints below the free edge.
      // An edge between consecutive free-edge points is the boundary itself (its midpoint may
      // lie above a concave stretch of the free edge).
      bool inside = c.y() < un.free_edge(c.x()) * scale;
      for (int k = 0; k < 3 && inside; ++k) {
        const int a = origin[t[k]], b = origin[t[(k + 1) % 3]];
        const int gap = std::abs(a - b);
        if (sm.free_edge[a] && sm.free_edge[b] && (gap == 1 || gap == num_edge - 1)) continue;
        const Eigen::Vector2d m = 0.5 * (pts[t[k]] + pts[t[(k + 1) % 3]]);
        inside = m.y() < un.free_edge(m.x()) * scale + 1e-9;
      }
      if (inside) sm.triangles.push_back({origin[t[0]], origin[t[1]], origin[t[2]]});
    }
  };
  triangulate();
  std::vector<char> movable(n, 0);
  for (int i = U; i < n; ++i) movable[i] = !sm.free_edge[i];
  for (int pass = 0; pass < 10; ++pass) {
    std::vector<Eigen::Vector2d> sum(n, Eigen::Vector2d::Zero());
    std::vector<int> count(n, 0);
    for (const auto& t : sm.triangles) {
      for (int k = 0; k < 3; ++k) {
        const int a = t[k], b = t[(k + 1) % 3];
        Eigen::Vector2d d = sm.plane[b] - sm.plane[a];
        d.x() -= P * std::round(d.x() / P);
        sum[a] += d;
        sum[b] -= d;
        ++count[a];
        ++count[b];
      }
    }
    for (int i = 0; i < n; ++i) {
      if (!movable[i] || count[i] == 0) continue;
      Eigen::Vector2d q = sm.plane[i] + 0.5 * sum[i] / count[i];
      q.x() -= P * std::floor(q.x() / P);
      if (q.y() > 0.2 * hd && q.y() < un.free_edge(q.x()) - 0.2 * hd) sm.plane[i] = q;
    }
  }
  triangulate();
  // A lattice point just under a steep, concave stretch of the free edge can lose every
  // triangle to the clipping (seen on detected surfaces, whose commissures are sharper): it
  // would be a node without an element, so it is dropped. The annulus points always stay.
  std::vector<char> used(static_cast<std::size_t>(n), 0);
  for (const auto& t : sm.triangles)
    for (int k = 0; k < 3; ++k) used[static_cast<std::size_t>(t[k])] = 1;
  for (int a : sm.annulus_column) used[static_cast<std::size_t>(a)] = 1;
  if (std::find(used.begin(), used.end(), 0) != used.end()) {
    std::vector<int> remap(static_cast<std::size_t>(n), -1);
    std::vector<Eigen::Vector2d> plane;
    std::vector<char> edge_flag;
    for (int i = 0; i < n; ++i) {
      if (!used[static_cast<std::size_t>(i)]) continue;
      remap[static_cast<std::size_t>(i)] = static_cast<int>(plane.size());
      plane.push_back(sm.plane[static_cast<std::size_t>(i)]);
      edge_flag.push_back(sm.free_edge[static_cast<std::size_t>(i)]);
    }
    for (auto& t : sm.triangles)
      for (int k = 0; k < 3; ++k) t[k] = remap[static_cast<std::size_t>(t[k])];
    for (int& a : sm.annulus_column) a = remap[static_cast<std::size_t>(a)];
    sm.plane = std::move(plane);
    sm.free_edge = std::move(edge_flag);
  }
  for (const auto& q : sm.plane) sm.st.push_back(un.st(q.x(), q.y()));
  return sm;
}

}  // namespace

double grid_roughness(const LeafletGrid& g) {
  // Fourth differences along u (periodic) and v vanish for cubic variation: a smooth but curved
  // surface (the annulus ring, the bowl of the leaflets) scores ~0.01 mm. Their median, not
  // their mean, so that the few columns with real kinks (commissural notches, clefts between
  // scallops) do not count. For white noise of SD sigma per coordinate a difference is
  // 3D normal with SD sqrt(70) sigma per axis, whose norm has median 1.538 sqrt(70) sigma:
  // the result estimates sigma.
  const int U = g.ures(), V = g.vres();
  std::vector<double> d;
  auto d4 = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                const Eigen::Vector3d& e, const Eigen::Vector3d& f) {
    d.push_back((a - 4.0 * b + 6.0 * c - 4.0 * e + f).norm());
  };
  for (int v = 1; v < V; ++v) {
    for (int u = 0; u < U; ++u) {
      d4(g.at(u - 2, v), g.at(u - 1, v), g.at(u, v), g.at(u + 1, v), g.at(u + 2, v));
      if (v >= 2 && v + 2 < V)
        d4(g.at(u, v - 2), g.at(u, v - 1), g.at(u, v), g.at(u, v + 1), g.at(u, v + 2));
    }
  }
  if (d.empty()) return 0.0;
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2] / (1.538 * std::sqrt(70.0));
}

void smooth_grid(LeafletGrid* g, int passes) {
  const int U = g->ures(), V = g->vres();
  auto step = [&](double factor) {
    LeafletGrid::Points next = g->points();
    for (int v = 1; v < V; ++v) {
      for (int u = 0; u < U; ++u) {
        Eigen::Vector3d mean = 0.5 * (g->at(u - 1, v) + g->at(u + 1, v));
        if (v + 1 < V) mean = 0.5 * mean + 0.25 * (g->at(u, v - 1) + g->at(u, v + 1));
        next.row(v * U + u) += factor * (mean - g->at(u, v)).transpose();
      }
    }
    g->points() = next;
  };
  for (int k = 0; k < passes; ++k) {
    step(0.5);    // lambda: smooth
    step(-0.53);  // mu: inflate back (Taubin 1995), so that the surface does not shrink
  }
}

ValveModel build_valve_model(const ValveSequence& seq, const ModelOptions& opt) {
  std::string err;
  if (!opt.is_valid(&err)) throw Error("valve model: " + err);
  if (seq.end_diastole < 0) throw Error("valve model: the sequence has no end-diastolic frame");
  const ValveFrame& ed = seq.frames.at(seq.end_diastole);
  if (!ed.la_surface) throw Error("valve model: leaflets are not observed at end-diastole");
  for (Landmark l : {Landmark::kAnterolateralPapillaryTip, Landmark::kPosteromedialPapillaryTip}) {
    if (!ed.observed(l)) {
      throw Error("valve model: " + std::string(name(l)) + " is not observed at end-diastole");
    }
  }
  ValveModel m;
  m.options = opt;
  m.papillary_ed[0] = ed.landmark(Landmark::kAnterolateralPapillaryTip);
  m.papillary_ed[1] = ed.landmark(Landmark::kPosteromedialPapillaryTip);
  const int U = opt.ures, L = opt.layers;
  if (!ed.la_surface->points().allFinite())
    throw Error("valve model: the end-diastolic leaflet surface has non-finite coordinates");
  LeafletGrid grid = *ed.la_surface;
  m.input_roughness_mm = grid_roughness(grid);
  if (opt.smoothing_roughness_mm > 0 && m.input_roughness_mm > opt.smoothing_roughness_mm) {
    while (m.smoothing_passes < opt.max_smoothing_passes &&
           grid_roughness(grid) > 0.1 * opt.smoothing_roughness_mm) {
      smooth_grid(&grid, 1);
      ++m.smoothing_passes;
    }
  }
  const Unrolled un(grid, U);
  const SurfaceMesh sm = mesh_surface(un, U, opt.vres, opt.refine_regions, opt.refine_factor);
  const int N = static_cast<int>(sm.plane.size());
  m.surface_nodes = N;
  m.surface_st.resize(N, 2);
  m.surface_plane.resize(N, 2);
  for (int i = 0; i < N; ++i) {
    m.surface_st.row(i) = sm.st[i].transpose();
    m.surface_plane.row(i) = sm.plane[i].transpose();
  }
  m.perimeter = un.perimeter();
  m.annulus_column = sm.annulus_column;
  m.surface_triangles.resize(static_cast<Eigen::Index>(sm.triangles.size()), 3);
  for (size_t f = 0; f < sm.triangles.size(); ++f) {
    for (int k = 0; k < 3; ++k)
      m.surface_triangles(static_cast<Eigen::Index>(f), k) = sm.triangles[f][k];
  }

  // Atrial surface points and vertex normals towards the ventricle: counter-clockwise in
  // (xi, depth) is the grid's (u, v) winding, whose normals face the ventricle.
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> X(N, 3),
      normal = Eigen::MatrixXd::Zero(N, 3);
  for (int i = 0; i < N; ++i) X.row(i) = un.position(sm.st[i]).transpose();
  for (const auto& t : sm.triangles) {
    const Eigen::Vector3d a = X.row(t[0]), b = X.row(t[1]), c = X.row(t[2]);
    const Eigen::Vector3d nrm = (b - a).cross(c - a);
    for (int k = 0; k < 3; ++k) normal.row(t[k]) += nrm.transpose();
  }
  for (int i = 0; i < N; ++i) {
    const double len = normal.row(i).norm();
    if (!(len > 0)) {
      throw Error("valve model: degenerate leaflet surface at grid coordinates (" +
                  std::to_string(sm.st[i][0]) + ", " + std::to_string(sm.st[i][1]) + ")");
    }
    normal.row(i) /= len;
  }
  auto anterior_at = [](double s) { return s < 0.5; };
  auto thickness = [&](double s) {
    return anterior_at(s) ? opt.al_thickness_mm : opt.pl_thickness_mm;
  };

  TetMesh& lin = m.linear;
  lin.V.resize(static_cast<Eigen::Index>(L + 1) * N, 3);
  for (int l = 0; l <= L; ++l) {
    for (int i = 0; i < N; ++i) {
      lin.V.row(m.node(i, l)) =
          X.row(i) + (static_cast<double>(l) / L) * thickness(sm.st[i][0]) * normal.row(i);
    }
  }
  // Prisms (triangle x layer) -> 3 tetrahedra, split by global node order so that the quad
  // faces shared by neighbouring prisms are cut along the same diagonal.
  std::vector<Eigen::Vector4i> tets;
  std::vector<int> tags;
  std::vector<Eigen::Vector3d> fibres;
  for (const auto& tri : sm.triangles) {
    // Element frame from the unrolled plane: circumferential d/dxi, radial d/ddepth.
    Eigen::Vector2d c2 = Eigen::Vector2d::Zero();
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector2d q = sm.plane[tri[k]];
      q.x() -= un.perimeter() * std::round((q.x() - sm.plane[tri[0]].x()) / un.perimeter());
      c2 += q / 3.0;
    }
    const double s_c = un.st(c2.x(), c2.y())[0];
    const double dx = 0.25 * un.perimeter() / U, dd = 0.25;
    Eigen::Vector3d tu =
        un.position(un.st(c2.x() + dx, c2.y())) - un.position(un.st(c2.x() - dx, c2.y()));
    Eigen::Vector3d tv = un.position(un.st(c2.x(), c2.y() + dd)) -
                         un.position(un.st(c2.x(), std::max(0.0, c2.y() - dd)));
    tu.normalize();
    tv = (tv - tu * tu.dot(tv)).normalized();
    const bool anterior = anterior_at(s_c);
    const double s_leaf = anterior ? 2.0 * s_c : 2.0 * s_c - 1.0;
    const double angle = fibre_angle(anterior, s_leaf);
    const Eigen::Vector3d fibre = std::cos(angle) * tu + std::sin(angle) * tv;
    std::array<int, 3> o = tri;
    std::sort(o.begin(), o.end());
    for (int l = 0; l < L; ++l) {
      const int a = m.node(o[0], l), b = m.node(o[1], l), c = m.node(o[2], l);
      const int a1 = m.node(o[0], l + 1), b1 = m.node(o[1], l + 1), c1 = m.node(o[2], l + 1);
      for (Eigen::Vector4i t : {Eigen::Vector4i(a, b, c, c1), Eigen::Vector4i(a, b, b1, c1),
                                Eigen::Vector4i(a, a1, b1, c1)}) {
        const Eigen::Vector3d p0 = lin.V.row(t[0]), p1 = lin.V.row(t[1]), p2 = lin.V.row(t[2]),
                              p3 = lin.V.row(t[3]);
        if ((p1 - p0).cross(p2 - p0).dot(p3 - p0) < 0) std::swap(t[1], t[2]);
        tets.push_back(t);
        tags.push_back(static_cast<int>(anterior ? LeafletTag::kAnterior : LeafletTag::kPosterior));
        fibres.push_back(fibre);
      }
    }
  }
  lin.T.resize(static_cast<Eigen::Index>(tets.size()), 4);
  lin.tag.resize(static_cast<Eigen::Index>(tets.size()));
  lin.fibre.resize(static_cast<Eigen::Index>(tets.size()), 3);
  for (size_t e = 0; e < tets.size(); ++e) {
    lin.T.row(static_cast<Eigen::Index>(e)) = tets[e].transpose();
    lin.tag[static_cast<Eigen::Index>(e)] = tags[e];
    lin.fibre.row(static_cast<Eigen::Index>(e)) = fibres[e].transpose();
  }
  lin.check("valve model");  // throws for an element inverted by the extrusion
  m.min_quality = 1.0;
  for (Eigen::Index e = 0; e < lin.T.rows(); ++e) {
    double longest = 0.0;
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j)
        longest = std::max(longest, (lin.V.row(lin.T(e, i)) - lin.V.row(lin.T(e, j))).norm());
    }
    const double q =
        6.0 * std::sqrt(2.0) * lin.volume(static_cast<int>(e)) / (longest * longest * longest);
    if (q < m.min_quality) {
      m.min_quality = q;
      m.worst_element = static_cast<int>(e);
    }
  }
  m.mesh = make_solid(lin, opt.order);
  if (opt.order == TetOrder::kQuadratic && opt.curved) {
    // Isoparametric rest geometry: each mid-edge node on the curved leaflet, at the midpoint of
    // its edge in the unrolled plane and through the thickness (straight-sided elements facet
    // the leaflet: ~0.1 mm at ures = 30, ~0.2 mm at ures = 20). Elements the curving would
    // distort (det J below a fifth of the straight element's) keep straight edges.
    const auto straight = m.mesh.V;
    auto unwrap = [&](Eigen::Vector2d q, const Eigen::Vector2d& ref) {
      q.x() -= un.perimeter() * std::round((q.x() - ref.x()) / un.perimeter());
      return q;
    };
    for (const auto& [edge, mid] : m.mesh.mid_edge) {
      const int ia = edge.first % N, la = edge.first / N, ib = edge.second % N,
                lb = edge.second / N;
      const Eigen::Vector2d qa = sm.plane[ia], qb = unwrap(sm.plane[ib], qa);
      const Eigen::Vector2d q = 0.5 * (qa + qb);
      const Eigen::Vector3d surface = un.position(un.st(q.x(), q.y()));
      const Eigen::Vector3d n = (normal.row(ia) + normal.row(ib)).transpose().normalized();
      const double t = 0.5 * (thickness(sm.st[ia][0]) + thickness(sm.st[ib][0]));
      const double tau = 0.5 * (la + lb) / static_cast<double>(L);
      if (n.allFinite()) m.mesh.V.row(mid) = (surface + tau * t * n).transpose();
    }
    // Straightening an element moves mid-edge nodes that its neighbours share, which can fold a
    // neighbour checked before it: repeat until a pass straightens nothing (an element is
    // straightened at most once, so this ends). Two fixed passes left one element of cohort seed
    // 2026's patient 18 folded at 40 x 40 x 3 layers on its widest frame, and its diastole
    // failed there.
    std::vector<char> straightened(static_cast<std::size_t>(m.mesh.num_elements()), 0);
    for (bool changed = true; changed;) {
      changed = false;
      for (int e = 0; e < m.mesh.num_elements(); ++e) {
        if (straightened[static_cast<std::size_t>(e)]) continue;
        CorotationalTet<10>::Nodes Xc, Xs;
        for (int a = 0; a < 10; ++a) {
          Xc.row(a) = m.mesh.V.row(m.mesh.T(e, a));
          Xs.row(a) = straight.row(m.mesh.T(e, a));
        }
        if (CorotationalTet<10>::min_jacobian_of(Xc) <
            0.2 * CorotationalTet<10>::min_jacobian_of(Xs)) {
          for (int a = 4; a < 10; ++a) m.mesh.V.row(m.mesh.T(e, a)) = straight.row(m.mesh.T(e, a));
          ++m.straight_elements;
          straightened[static_cast<std::size_t>(e)] = 1;
          changed = true;
        }
      }
    }
  }

  // Prescribed: the annulus row on every layer (and the mid-edge nodes between those).
  std::set<int> ann;
  for (int l = 0; l <= L; ++l) {
    for (int i : sm.annulus_column) ann.insert(m.node(i, l));
  }
  if (opt.order == TetOrder::kQuadratic) {
    for (const auto& [edge, mid] : m.mesh.mid_edge) {
      if (ann.count(edge.first) && ann.count(edge.second)) ann.insert(mid);
    }
  }
  m.annulus_nodes.assign(ann.begin(), ann.end());

  // Pressure acts on the ventricular surface (layer L), triangles facing the ventricle.
  for (const auto& t : sm.triangles)
    m.ventricular_faces.emplace_back(m.node(t[0], L), m.node(t[1], L), m.node(t[2], L));

  // Chordae (Mansi et al. 2012, Sec. 2.2) at the surface node nearest to their site; each to the
  // tip on its side.
  auto nearest = [&](double s_site, double t_site, bool on_free_edge) {
    const double xi = un.xi(s_site);
    const double depth = t_site * un.free_edge(xi);
    int best = -1;
    double best_d = std::numeric_limits<double>::infinity();
    for (int i = 0; i < N; ++i) {
      if (on_free_edge && !sm.free_edge[i]) continue;
      double dx = sm.plane[i].x() - xi;
      dx -= un.perimeter() * std::round(dx / un.perimeter());
      const double d = std::hypot(dx, sm.plane[i].y() - depth);
      if (d < best_d) {
        best_d = d;
        best = i;
      }
    }
    return best;
  };
  auto add = [&](double s_site, double t_site, bool marginal) {
    s_site -= std::floor(s_site);
    const int i = nearest(s_site, t_site, marginal);
    const bool anterolateral = s_site < 0.25 || s_site >= 0.75;
    ModelChorda c;
    c.node = m.node(i, L);
    c.papillary = anterolateral ? 0 : 1;
    c.marginal = marginal;
    c.group = static_cast<ChordaeGroup>((anterolateral ? 0 : 2) + (marginal ? 0 : 1));
    c.s = sm.st[i][0];
    c.t = sm.st[i][1];
    for (int l = 0; l <= L; ++l) {
      c.nodes.push_back(m.node(i, l));
      if (l > 0 && opt.order == TetOrder::kQuadratic) {
        const int mid = m.mesh.mid_node(m.node(i, l - 1), m.node(i, l));
        if (mid >= 0) c.nodes.push_back(mid);
      }
    }
    Eigen::Vector3d insertion = Eigen::Vector3d::Zero();
    for (int k : c.nodes) insertion += m.mesh.V.row(k).transpose();
    insertion /= static_cast<double>(c.nodes.size());
    c.ed_length = (insertion - m.papillary_ed[c.papillary]).norm();
    m.chordae.push_back(c);
  };
  for (int k = 0; k < opt.marginal_chordae; ++k)
    add(static_cast<double>(k) / opt.marginal_chordae, 1.0, true);
  for (int i = 0; i < 4; ++i) {
    const double site = (2 * i + 1) / 8.0;
    add(site, 0.5, false);
    add(site + 1.0 / 30.0, 0.5, false);
  }
  return m;
}

AtrialSampler make_atrial_sampler(const ValveModel& m, int ures, int vres) {
  if (ures < 8 || ures % 2 || vres < 3)
    throw Error("atrial sampler: ures must be even and >= 8, vres >= 3");
  AtrialSampler out;
  out.ures = ures;
  out.vres = vres;
  const auto& st = m.surface_st;
  const Eigen::Index F = m.surface_triangles.rows();
  // Barycentric coordinates of q in triangle f, unwrapped around the triangle's first vertex
  // (s is periodic).
  auto barycentric = [&](Eigen::Index f, const Eigen::Vector2d& q, Eigen::Vector3d* bw) {
    Eigen::Vector2d p[3];
    for (int k = 0; k < 3; ++k) p[k] = st.row(m.surface_triangles(f, k)).transpose();
    for (int k = 1; k < 3; ++k) p[k].x() -= std::round(p[k].x() - p[0].x());
    Eigen::Vector2d qq = q;
    qq.x() -= std::round(qq.x() - p[0].x());
    const Eigen::Vector2d e1 = p[1] - p[0], e2 = p[2] - p[0], r = qq - p[0];
    const double det = e1.x() * e2.y() - e1.y() * e2.x();
    if (std::abs(det) < 1e-300) return false;
    const double b1 = (r.x() * e2.y() - r.y() * e2.x()) / det;
    const double b2 = (e1.x() * r.y() - e1.y() * r.x()) / det;
    *bw = Eigen::Vector3d(1.0 - b1 - b2, b1, b2);
    return true;
  };
  // Buckets over the unrolled plane (s periodic in [0, 1), t in [0, 1]) holding the triangles
  // whose bounding box meets them, in index order: a point's first containing triangle is found
  // among its bucket's, as a scan of every triangle would find it (ascending indices).
  const int nb = std::max(4, static_cast<int>(std::sqrt(static_cast<double>(F))));
  std::vector<std::vector<int>> bucket(static_cast<size_t>(nb) * nb);
  auto t_cell = [&](double t) {
    return std::clamp(static_cast<int>(std::floor(t * nb)), 0, nb - 1);
  };
  for (Eigen::Index f = 0; f < F; ++f) {
    double x0 = st(m.surface_triangles(f, 0), 0), x1 = x0, y0 = st(m.surface_triangles(f, 0), 1),
           y1 = y0;
    for (int k = 1; k < 3; ++k) {
      double x = st(m.surface_triangles(f, k), 0);
      x -= std::round(x - st(m.surface_triangles(f, 0), 0));
      x0 = std::min(x0, x);
      x1 = std::max(x1, x);
      y0 = std::min(y0, st(m.surface_triangles(f, k), 1));
      y1 = std::max(y1, st(m.surface_triangles(f, k), 1));
    }
    const int i0 = static_cast<int>(std::floor(x0 * nb)) - 1,
              i1 = static_cast<int>(std::floor(x1 * nb)) + 1;
    for (int j = std::max(0, t_cell(y0) - 1); j <= std::min(nb - 1, t_cell(y1) + 1); ++j)
      for (int i = i0; i <= i1; ++i) {
        std::vector<int>& b = bucket[static_cast<size_t>(j) * nb + ((i % nb) + nb) % nb];
        if (b.empty() || b.back() != f) b.push_back(static_cast<int>(f));
      }
  }
  for (int v = 0; v < vres; ++v) {
    for (int u = 0; u < ures; ++u) {
      const Eigen::Vector2d q(static_cast<double>(u) / ures, static_cast<double>(v) / (vres - 1));
      double best = -std::numeric_limits<double>::infinity();
      std::array<int, 3> nodes{};
      Eigen::Vector3d w, bw;
      const std::vector<int>& cand =
          bucket[static_cast<size_t>(t_cell(q.y())) * nb +
                 std::clamp(static_cast<int>(std::floor(q.x() * nb)), 0, nb - 1)];
      int inside = -1;
      for (int f : cand) {
        if (barycentric(f, q, &bw) && bw.minCoeff() >= 0) {
          inside = f;
          break;
        }
      }
      if (inside >= 0) {
        barycentric(inside, q, &w);
        best = w.minCoeff();
        for (int k = 0; k < 3; ++k) nodes[k] = m.surface_triangles(inside, k);
      } else {
        // Outside every triangle of its bucket: the scan over all (the free-edge curve between
        // boundary points lies outside every triangle; then the closest in barycentric terms).
        for (Eigen::Index f = 0; f < F; ++f) {
          if (!barycentric(f, q, &bw)) continue;
          if (bw.minCoeff() > best) {
            best = bw.minCoeff();
            w = bw;
            for (int k = 0; k < 3; ++k) nodes[k] = m.surface_triangles(f, k);
            if (best >= 0) break;
          }
        }
      }
      // Outside every triangle (the free-edge curve between boundary points): clamp.
      if (best < 0) {
        w = w.cwiseMax(0.0);
        w /= w.sum();
      }
      out.nodes.push_back(nodes);
      std::array<int, 3> mids{-1, -1, -1};
      if (m.mesh.order == TetOrder::kQuadratic) {
        for (int k = 0; k < 3; ++k) mids[k] = m.mesh.mid_node(nodes[k], nodes[(k + 1) % 3]);
      }
      out.mids.push_back(mids);
      out.weights.push_back(w);
    }
  }
  return out;
}

AtrialSampler ventricular_sampler(const ValveModel& m, const AtrialSampler& atrial) {
  AtrialSampler out = atrial;
  const int L = m.options.layers;
  for (size_t k = 0; k < out.nodes.size(); ++k) {
    for (int j = 0; j < 3; ++j) out.nodes[k][j] = m.node(atrial.nodes[k][j], L);
    if (m.mesh.order == TetOrder::kQuadratic) {
      for (int j = 0; j < 3; ++j)
        out.mids[k][j] = m.mesh.mid_node(out.nodes[k][j], out.nodes[k][(j + 1) % 3]);
    }
  }
  return out;
}

LeafletGrid sample_atrial(const AtrialSampler& sp, const Eigen::VectorXd& x) {
  LeafletGrid::Points P(static_cast<Eigen::Index>(sp.nodes.size()), 3);
  for (size_t k = 0; k < sp.nodes.size(); ++k) {
    const Eigen::Vector3d& L = sp.weights[k];
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    const bool quadratic =
        k < sp.mids.size() && sp.mids[k][0] >= 0 && sp.mids[k][1] >= 0 && sp.mids[k][2] >= 0;
    if (quadratic) {
      // 6-node triangle: corners L_i (2 L_i - 1), mid-edge ij 4 L_i L_j.
      for (int j = 0; j < 3; ++j) {
        p += L[j] * (2.0 * L[j] - 1.0) * x.segment<3>(3 * sp.nodes[k][j]);
        p += 4.0 * L[j] * L[(j + 1) % 3] * x.segment<3>(3 * sp.mids[k][j]);
      }
    } else {
      for (int j = 0; j < 3; ++j) p += L[j] * x.segment<3>(3 * sp.nodes[k][j]);
    }
    P.row(static_cast<Eigen::Index>(k)) = p.transpose();
  }
  return LeafletGrid(sp.ures, sp.vres, std::move(P));
}

}  // namespace mvtwin::forward
