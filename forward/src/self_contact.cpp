#include "mvtwin/forward/self_contact.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include <Eigen/Geometry>

#include "mvtwin/core/error.h"
#include "mvtwin/core/point_triangle_distance.h"

namespace mvtwin::forward {
namespace {

/// Barycentric weights of a point q lying on the triangle (a, b, c).
Eigen::Vector3d barycentric(const Eigen::Vector3d& q, const Eigen::Vector3d& a,
                            const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d e0 = b - a, e1 = c - a, r = q - a;
  const double d00 = e0.dot(e0), d01 = e0.dot(e1), d11 = e1.dot(e1), d20 = r.dot(e0),
               d21 = r.dot(e1);
  const double den = d00 * d11 - d01 * d01;
  if (!(std::abs(den) > 1e-300)) return {1.0, 0.0, 0.0};
  const double v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
  return {1.0 - v - w, v, w};
}

struct CellKey {
  static std::int64_t of(const Eigen::Vector3d& p, double h) {
    const auto i = static_cast<std::int64_t>(std::floor(p.x() / h)) & 0x1fffff;
    const auto j = static_cast<std::int64_t>(std::floor(p.y() / h)) & 0x1fffff;
    const auto k = static_cast<std::int64_t>(std::floor(p.z() / h)) & 0x1fffff;
    return (i << 42) | (j << 21) | k;
  }
};

}  // namespace

SelfContact::Surface SelfContact::valve_surface(const ValveModel& m) {
  Surface s;
  const int N = m.surface_nodes, L = m.options.layers;
  s.plane = m.surface_plane;
  s.period = m.perimeter;
  std::vector<double> area(N, 0.0);
  for (Eigen::Index f = 0; f < m.surface_triangles.rows(); ++f) {
    const Eigen::Vector3d a = m.linear.V.row(m.surface_triangles(f, 0)),
                          b = m.linear.V.row(m.surface_triangles(f, 1)),
                          c = m.linear.V.row(m.surface_triangles(f, 2));
    const double A = 0.5 * (b - a).cross(c - a).norm();
    for (int k = 0; k < 3; ++k) area[m.surface_triangles(f, k)] += A / 3.0;
  }
  for (int layer : {0, L}) {
    for (int i = 0; i < N; ++i) {
      s.vertices.push_back(m.node(i, layer));
      s.vertex_plane.push_back(i);
      s.vertex_area.push_back(area[i]);
    }
    for (Eigen::Index f = 0; f < m.surface_triangles.rows(); ++f) {
      std::array<int, 3> t, q;
      for (int k = 0; k < 3; ++k) {
        q[k] = m.surface_triangles(f, k);
        t[k] = m.node(q[k], layer);
      }
      s.triangles.push_back(t);
      s.triangle_plane.push_back(q);
    }
  }
  return s;
}

SelfContact::SelfContact(Surface surface, const Options& o) : opt_(o), s_(std::move(surface)) {
  if (!(o.alarm_mm > o.contact_mm && o.contact_mm >= 0.0)) {
    throw Error("self-contact: need alarm distance > contact distance >= 0");
  }
  if (!(o.friction >= 0.0 && o.friction_slip_mm_per_s > 0.0 && o.stiffness_per_area >= 0.0 &&
        o.margin_mm > 0.0 && o.exclusion_mm >= 0.0)) {
    throw Error("self-contact: friction, stiffness, margin and exclusion must be >= 0");
  }
  if (s_.vertices.size() != s_.vertex_plane.size() || s_.vertices.size() != s_.vertex_area.size() ||
      s_.triangles.size() != s_.triangle_plane.size()) {
    throw Error("self-contact: surface arrays differ in size");
  }
}

void SelfContact::full_search(const Eigen::VectorXd& x) {
  ++searches_;
  pairs_.clear();
  const double reach = opt_.alarm_mm + opt_.margin_mm;
  const double h = reach;
  std::unordered_map<std::int64_t, std::vector<int>> grid;
  grid.reserve(4 * s_.triangles.size());
  for (size_t t = 0; t < s_.triangles.size(); ++t) {
    Eigen::Vector3d lo = x.segment<3>(3 * s_.triangles[t][0]), hi = lo;
    for (int k = 1; k < 3; ++k) {
      lo = lo.cwiseMin(x.segment<3>(3 * s_.triangles[t][k]));
      hi = hi.cwiseMax(x.segment<3>(3 * s_.triangles[t][k]));
    }
    lo.array() -= reach;
    hi.array() += reach;
    for (double X = std::floor(lo.x() / h) * h; X <= hi.x(); X += h) {
      for (double Y = std::floor(lo.y() / h) * h; Y <= hi.y(); Y += h) {
        for (double Z = std::floor(lo.z() / h) * h; Z <= hi.z(); Z += h) {
          grid[CellKey::of(Eigen::Vector3d(X + 0.5 * h, Y + 0.5 * h, Z + 0.5 * h), h)].push_back(
              static_cast<int>(t));
        }
      }
    }
  }
  double nearest = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < s_.vertices.size(); ++i) {
    const Eigen::Vector3d p = x.segment<3>(3 * s_.vertices[i]);
    const auto it = grid.find(CellKey::of(p, h));
    if (it == grid.end()) continue;
    Pair best{};
    best.distance = std::numeric_limits<double>::infinity();
    const Eigen::Vector2d pv = s_.plane.row(s_.vertex_plane[i]).transpose();
    for (int t : it->second) {
      bool excluded = false;
      for (int k = 0; k < 3 && !excluded; ++k) {
        Eigen::Vector2d d = s_.plane.row(s_.triangle_plane[t][k]).transpose() - pv;
        if (s_.period > 0) d.x() -= s_.period * std::round(d.x() / s_.period);
        excluded = d.norm() < opt_.exclusion_mm;
      }
      if (excluded) continue;
      const Eigen::Vector3d a = x.segment<3>(3 * s_.triangles[t][0]),
                            b = x.segment<3>(3 * s_.triangles[t][1]),
                            c = x.segment<3>(3 * s_.triangles[t][2]);
      const Eigen::Vector3d q = closest_point_on_triangle(p, a, b, c);
      const double d = (p - q).norm();
      nearest = std::min(nearest, d);
      if (d < best.distance) {
        best.distance = d;
        best.vertex = s_.vertices[i];
        best.tri = s_.triangles[t];
        best.weights = barycentric(q, a, b, c);
        best.normal = d > 1e-12 ? Eigen::Vector3d((p - q) / d) : (b - a).cross(c - a).normalized();
      }
    }
    if (best.distance < opt_.alarm_mm) {
      best.area = s_.vertex_area[i];
      pairs_.push_back(best);
    }
  }
  min_distance_ = nearest;
  far_ = !(nearest < reach);
  if (far_) x_search_ = x;
}

int SelfContact::detect(const Eigen::VectorXd& x) {
  if (far_ && x_search_.size() == x.size()) {
    double moved = 0.0;
    for (int v : s_.vertices) moved = std::max(moved, (x.segment<3>(3 * v) - x_search_.segment<3>(3 * v)).norm());
    // Every vertex and triangle corner moved less than margin/2: no pair came within reach.
    if (moved < 0.5 * opt_.margin_mm) {
      ++skipped_;
      pairs_.clear();
      return 0;
    }
  }
  full_search(x);
  return static_cast<int>(pairs_.size());
}

double SelfContact::add(const Eigen::VectorXd& v, Eigen::VectorXd* f,
                        std::vector<Eigen::Triplet<double>>* trip, double scale_k,
                        double scale_c) const {
  double energy = 0.0;
  for (const Pair& pr : pairs_) {
    const double gap = opt_.alarm_mm - pr.distance;
    if (gap <= 0) continue;
    const double k = opt_.stiffness_per_area * pr.area;
    const double fn = k * gap;
    energy += 0.5 * k * gap * gap;
    const int nodes[4] = {pr.vertex, pr.tri[0], pr.tri[1], pr.tri[2]};
    const double c[4] = {1.0, -pr.weights[0], -pr.weights[1], -pr.weights[2]};
    const Eigen::Vector3d& n = pr.normal;
    // Normal force pushes the vertex away from the triangle (and the triangle back).
    for (int a = 0; a < 4; ++a) f->segment<3>(3 * nodes[a]) += c[a] * fn * n;
    // Lagged Coulomb friction on the relative tangential velocity.
    Eigen::Vector3d vrel = Eigen::Vector3d::Zero();
    for (int a = 0; a < 4; ++a) vrel += c[a] * v.segment<3>(3 * nodes[a]);
    const Eigen::Vector3d vt = vrel - n * n.dot(vrel);
    const double speed = vt.norm();
    const double eta = opt_.friction * fn / std::max(speed, opt_.friction_slip_mm_per_s);
    for (int a = 0; a < 4; ++a) f->segment<3>(3 * nodes[a]) -= c[a] * eta * vt;
    const Eigen::Matrix3d K = k * n * n.transpose();
    const Eigen::Matrix3d D = eta * (Eigen::Matrix3d::Identity() - n * n.transpose());
    // Only the diagonal blocks of the Gauss-Newton stiffness: the couplings between the vertex
    // and the triangle would change the sparsity pattern whenever the pairs change, and each
    // new pattern costs a symbolic analysis. The blocks kept are positive semi-definite.
    for (int a = 0; a < 4; ++a) {
      const Eigen::Matrix3d B = c[a] * c[a] * (scale_k * K + scale_c * D);
      for (int r = 0; r < 3; ++r) {
        for (int s = 0; s < 3; ++s) trip->emplace_back(3 * nodes[a] + r, 3 * nodes[a] + s, B(r, s));
      }
    }
  }
  return energy;
}

}  // namespace mvtwin::forward
