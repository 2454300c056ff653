#include "mvtwin/forward/self_contact.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
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
  static std::int64_t of_index(std::int64_t i, std::int64_t j, std::int64_t k) {
    return ((i & 0x1fffff) << 42) | ((j & 0x1fffff) << 21) | (k & 0x1fffff);
  }
  static std::int64_t of(const Eigen::Vector3d& p, double h) {
    return of_index(static_cast<std::int64_t>(std::floor(p.x() / h)),
                    static_cast<std::int64_t>(std::floor(p.y() / h)),
                    static_cast<std::int64_t>(std::floor(p.z() / h)));
  }
};

}  // namespace

SelfContact::Surface SelfContact::valve_surface(const ValveModel& m) {
  // The atrial and ventricular surfaces. For quadratic elements each surface triangle is split
  // at its mid-edge nodes into 4, and the mid-edge nodes are contact vertices too: a quadratic
  // face loaded at its corners only is loaded inconsistently (uniform pressure puts nothing on
  // the corners) and its elements invert under concentrated contact forces.
  Surface s;
  const int N = m.surface_nodes, L = m.options.layers;
  const bool quadratic = m.mesh.order == TetOrder::kQuadratic;
  std::vector<Eigen::Vector2d> plane;
  for (int i = 0; i < N; ++i) plane.push_back(m.surface_plane.row(i).transpose());
  s.period = m.perimeter;
  std::map<int, int> plane_of_node;   // contact node -> plane index
  std::map<int, double> area_of_node;
  auto plane_index = [&](int node, int sa, int sb) {
    const auto it = plane_of_node.find(node);
    if (it != plane_of_node.end()) return it->second;
    Eigen::Vector2d q = plane[sa];
    if (sb >= 0) {
      Eigen::Vector2d r = plane[sb];
      r.x() -= s.period * std::round((r.x() - q.x()) / s.period);
      q = 0.5 * (q + r);
    }
    plane.push_back(q);
    return plane_of_node[node] = static_cast<int>(plane.size()) - 1;
  };
  for (int layer : {0, L}) {
    for (Eigen::Index f = 0; f < m.surface_triangles.rows(); ++f) {
      int sid[3], nd[3], pl[3];
      for (int k = 0; k < 3; ++k) {
        sid[k] = m.surface_triangles(f, k);
        nd[k] = m.node(sid[k], layer);
        pl[k] = plane_index(nd[k], sid[k], -1);
      }
      const int group = m.surface_st(sid[0], 0) < 0.5 ? 0 : 1;
      std::vector<std::array<int, 3>> sub, sub_plane;
      if (quadratic) {
        int mid[3], mpl[3];
        for (int k = 0; k < 3; ++k) {
          const int a = k, b = (k + 1) % 3;
          mid[k] = m.mesh.mid_node(nd[a], nd[b]);
          if (mid[k] < 0) throw Error("self-contact: surface edge without a mid-edge node");
          mpl[k] = plane_index(mid[k], sid[a], sid[b]);
        }
        // corners 0,1,2; mids 01, 12, 20
        sub = {{nd[0], mid[0], mid[2]}, {mid[0], nd[1], mid[1]}, {mid[2], mid[1], nd[2]},
               {mid[0], mid[1], mid[2]}};
        sub_plane = {{pl[0], mpl[0], mpl[2]}, {mpl[0], pl[1], mpl[1]}, {mpl[2], mpl[1], pl[2]},
                     {mpl[0], mpl[1], mpl[2]}};
      } else {
        sub = {{nd[0], nd[1], nd[2]}};
        sub_plane = {{pl[0], pl[1], pl[2]}};
      }
      for (size_t k = 0; k < sub.size(); ++k) {
        const Eigen::Vector3d a = m.mesh.V.row(sub[k][0]), b = m.mesh.V.row(sub[k][1]),
                              c = m.mesh.V.row(sub[k][2]);
        const double A = 0.5 * (b - a).cross(c - a).norm();
        for (int j = 0; j < 3; ++j) area_of_node[sub[k][j]] += A / 3.0;
        s.triangles.push_back(sub[k]);
        s.triangle_plane.push_back(sub_plane[k]);
        s.triangle_group.push_back(group);
      }
    }
  }
  for (const auto& [node, area] : area_of_node) {
    s.vertices.push_back(node);
    s.vertex_plane.push_back(plane_of_node.at(node));
    s.vertex_area.push_back(area);
  }
  s.plane.resize(static_cast<Eigen::Index>(plane.size()), 2);
  for (size_t i = 0; i < plane.size(); ++i) s.plane.row(static_cast<Eigen::Index>(i)) = plane[i].transpose();
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
      s_.triangles.size() != s_.triangle_plane.size() ||
      (!s_.triangle_group.empty() && s_.triangle_group.size() != s_.triangles.size())) {
    throw Error("self-contact: surface arrays differ in size");
  }

}

void SelfContact::full_search(const Eigen::VectorXd& x) {
  ++searches_;
  // Sides of the pairs already known are kept: a vertex that was pushed through a triangle must
  // be pushed back, not further.
  std::unordered_map<std::int64_t, signed char> known;
  known.reserve(candidates_.size());
  const auto key = [&](int i, int t) {
    return static_cast<std::int64_t>(i) * static_cast<std::int64_t>(s_.triangles.size()) + t;
  };
  for (const Candidate& c : candidates_) known[key(c.vertex, c.triangle)] = c.side;
  candidates_.clear();
  const double reach = opt_.alarm_mm + opt_.margin_mm;
  const double h = reach;
  // Vertices binned once in cells of size `reach` (sorted by cell); each triangle visits the
  // cells its box, grown by `reach`, overlaps.
  std::vector<std::pair<std::int64_t, int>> cells;
  cells.reserve(s_.vertices.size());
  for (size_t i = 0; i < s_.vertices.size(); ++i)
    cells.emplace_back(CellKey::of(x.segment<3>(3 * s_.vertices[i]), h), static_cast<int>(i));
  std::sort(cells.begin(), cells.end());
  for (size_t t = 0; t < s_.triangles.size(); ++t) {
    const Eigen::Vector3d a = x.segment<3>(3 * s_.triangles[t][0]),
                          b = x.segment<3>(3 * s_.triangles[t][1]),
                          c = x.segment<3>(3 * s_.triangles[t][2]);
    const Eigen::Vector3d lo = a.cwiseMin(b).cwiseMin(c).array() - reach;
    const Eigen::Vector3d hi = a.cwiseMax(b).cwiseMax(c).array() + reach;
    const auto cell_lo = [&](double v) { return static_cast<std::int64_t>(std::floor(v / h)); };
    for (std::int64_t I = cell_lo(lo.x()); I <= cell_lo(hi.x()); ++I) {
      for (std::int64_t J = cell_lo(lo.y()); J <= cell_lo(hi.y()); ++J) {
        for (std::int64_t K = cell_lo(lo.z()); K <= cell_lo(hi.z()); ++K) {
          const std::int64_t cell = CellKey::of_index(I, J, K);
          auto it = std::lower_bound(cells.begin(), cells.end(), std::make_pair(cell, -1));
          for (; it != cells.end() && it->first == cell; ++it) {
            const int i = it->second;
            const Eigen::Vector3d p = x.segment<3>(3 * s_.vertices[i]);
            if ((p.array() < lo.array()).any() || (p.array() > hi.array()).any()) continue;
            const Eigen::Vector2d pv = s_.plane.row(s_.vertex_plane[i]).transpose();
            bool excluded = false;
            for (int k = 0; k < 3 && !excluded; ++k) {
              Eigen::Vector2d d = s_.plane.row(s_.triangle_plane[t][k]).transpose() - pv;
              if (s_.period > 0) d.x() -= s_.period * std::round(d.x() / s_.period);
              excluded = d.norm() < opt_.exclusion_mm;
            }
            if (excluded) continue;
            const Eigen::Vector3d q = closest_point_on_triangle(p, a, b, c);
            if ((p - q).norm() < reach) {
              // The side is learnt the first time the vertex is over the face (detect()); a
              // vertex near the triangle but beyond its edges may be on either side of its plane.
              const auto k2 = known.find(key(i, static_cast<int>(t)));
              const signed char side = k2 != known.end() ? k2->second : static_cast<signed char>(0);
              candidates_.push_back({i, static_cast<int>(t), side});
            }
          }
        }
      }
    }
  }
  // Grouped by vertex (detect() walks each vertex's candidates together), in a fixed order.
  std::sort(candidates_.begin(), candidates_.end(), [](const Candidate& p, const Candidate& q) {
    return p.vertex != q.vertex ? p.vertex < q.vertex : p.triangle < q.triangle;
  });
  x_search_ = x;
}

int SelfContact::detect(const Eigen::VectorXd& x) {
  // Verlet list: the candidates (pairs within alarm + margin at the last search) hold every
  // pair within the alarm distance while no node has moved by more than margin / 2 since.
  bool fresh = x_search_.size() == x.size();
  if (fresh) {
    double moved = 0.0;
    for (int v : s_.vertices)
      moved = std::max(moved, (x.segment<3>(3 * v) - x_search_.segment<3>(3 * v)).norm());
    fresh = moved < 0.5 * opt_.margin_mm;
  }
  if (fresh) {
    ++reused_;
  } else {
    full_search(x);
  }
  pairs_.clear();
  min_distance_ = std::numeric_limits<double>::infinity();
  // Closest candidate triangle per vertex and triangle group.
  size_t k = 0;
  while (k < candidates_.size()) {
    const int i = candidates_[k].vertex;
    const Eigen::Vector3d p = x.segment<3>(3 * s_.vertices[i]);
    std::array<Pair, 2> best{};
    for (Pair& b : best) b.distance = std::numeric_limits<double>::infinity();
    for (; k < candidates_.size() && candidates_[k].vertex == i; ++k) {
      const int t = candidates_[k].triangle;
      const int g = s_.triangle_group.empty() ? 0 : (s_.triangle_group[t] != 0);
      const Eigen::Vector3d a = x.segment<3>(3 * s_.triangles[t][0]),
                            b = x.segment<3>(3 * s_.triangles[t][1]),
                            c = x.segment<3>(3 * s_.triangles[t][2]);
      const Eigen::Vector3d q = closest_point_on_triangle(p, a, b, c);
      const Eigen::Vector3d w = barycentric(q, a, b, c);
      // Over the face: distance signed by the side the vertex came from, so that a vertex
      // pushed through is pushed back. Beyond an edge or corner (around the free edge): the
      // plain distance.
      Eigen::Vector3d n;
      double d;
      if (w.minCoeff() > 1e-9) {
        n = (b - a).cross(c - a).normalized();
        if (candidates_[k].side == 0) candidates_[k].side = n.dot(p - q) >= 0 ? 1 : -1;
        n *= candidates_[k].side;
        d = n.dot(p - q);
      } else {
        d = (p - q).norm();
        n = d > 1e-12 ? Eigen::Vector3d((p - q) / d) : (b - a).cross(c - a).normalized();
      }
      if (d < best[g].distance) {
        best[g].distance = d;
        best[g].vertex = s_.vertices[i];
        best[g].tri = s_.triangles[t];
        best[g].weights = w;
        best[g].normal = n;
        best[g].area = 0.5 * (b - a).cross(c - a).norm();
      }
    }
    for (Pair& b : best) {
      min_distance_ = std::min(min_distance_, b.distance);
      if (b.distance < opt_.alarm_mm) {
        // A free-edge vertex pressed edge-on against a face stands for little area of its own;
        // the face it presses on carries the load, so the larger of the two areas sets k.
        b.area = std::max(b.area, s_.vertex_area[i]);
        pairs_.push_back(b);
      }
    }
  }
  return static_cast<int>(pairs_.size());
}

bool SelfContact::step_is_safe(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1,
                               double* worst) const {
  double m = 0.0;
  for (const Candidate& c : candidates_) {
    m = std::max(m, (x1.segment<3>(3 * s_.vertices[c.vertex]) -
                     x0.segment<3>(3 * s_.vertices[c.vertex])).norm());
    for (int k = 0; k < 3; ++k) {
      const int n = s_.triangles[c.triangle][k];
      m = std::max(m, (x1.segment<3>(3 * n) - x0.segment<3>(3 * n)).norm());
    }
  }
  if (worst) *worst = m;
  return m <= opt_.alarm_mm - opt_.contact_mm;
}

void SelfContact::law(double d, double k, double* force, double* stiffness) const {
  const double da = opt_.alarm_mm, dc = opt_.contact_mm;
  if (d >= da) {
    *force = *stiffness = 0.0;
    return;
  }
  *force = k * (da - d);
  *stiffness = k;
  if (d < dc && dc > 0) {
    const double kw = opt_.wall_factor * k;
    *force += kw * (dc - d) * (dc - d) / (2.0 * dc);
    *stiffness += kw * (dc - d) / dc;
  }
}

double SelfContact::add_forces(const Eigen::VectorXd& v, Eigen::VectorXd* f) {
  double energy = 0.0;
  const double da = opt_.alarm_mm, dc = opt_.contact_mm;
  for (Pair& pr : pairs_) {
    pr.force = pr.stiffness = pr.eta = 0.0;
    if (pr.distance >= da) continue;
    const double k = opt_.stiffness_per_area * pr.area;
    law(pr.distance, k, &pr.force, &pr.stiffness);
    energy += 0.5 * k * (da - pr.distance) * (da - pr.distance);
    if (pr.distance < dc && dc > 0) {
      energy += opt_.wall_factor * k * std::pow(dc - pr.distance, 3) / (6.0 * dc);
    }
    const int nodes[4] = {pr.vertex, pr.tri[0], pr.tri[1], pr.tri[2]};
    const double c[4] = {1.0, -pr.weights[0], -pr.weights[1], -pr.weights[2]};
    const Eigen::Vector3d& n = pr.normal;
    // Normal force pushes the vertex away from the triangle (and the triangle back).
    for (int a = 0; a < 4; ++a) f->segment<3>(3 * nodes[a]) += c[a] * pr.force * n;
    // Lagged Coulomb friction on the relative tangential velocity.
    Eigen::Vector3d vrel = Eigen::Vector3d::Zero();
    for (int a = 0; a < 4; ++a) vrel += c[a] * v.segment<3>(3 * nodes[a]);
    const Eigen::Vector3d vt = vrel - n * n.dot(vrel);
    pr.eta = opt_.friction * pr.force / std::max(vt.norm(), opt_.friction_slip_mm_per_s);
    for (int a = 0; a < 4; ++a) f->segment<3>(3 * nodes[a]) -= c[a] * pr.eta * vt;
  }
  return energy;
}

void SelfContact::multiply(const Eigen::VectorXd& p, double scale_k, double scale_c,
                           Eigen::VectorXd* y) const {
  for (const Pair& pr : pairs_) {
    if (pr.stiffness == 0.0 && pr.eta == 0.0) continue;
    const int nodes[4] = {pr.vertex, pr.tri[0], pr.tri[1], pr.tri[2]};
    const double c[4] = {1.0, -pr.weights[0], -pr.weights[1], -pr.weights[2]};
    const Eigen::Vector3d& n = pr.normal;
    Eigen::Vector3d jp = Eigen::Vector3d::Zero();
    for (int a = 0; a < 4; ++a) jp += c[a] * p.segment<3>(3 * nodes[a]);
    const double jn = n.dot(jp);
    const Eigen::Vector3d t =
        scale_k * pr.stiffness * jn * n + scale_c * pr.eta * (jp - jn * n);
    for (int a = 0; a < 4; ++a) y->segment<3>(3 * nodes[a]) += c[a] * t;
  }
}

void SelfContact::add_diagonal_blocks(double scale_k, double scale_c,
                                      SymmetricBlockMatrix* A) const {
  for (const Pair& pr : pairs_) {
    if (pr.stiffness == 0.0 && pr.eta == 0.0) continue;
    const int nodes[4] = {pr.vertex, pr.tri[0], pr.tri[1], pr.tri[2]};
    const double c[4] = {1.0, -pr.weights[0], -pr.weights[1], -pr.weights[2]};
    const Eigen::Matrix3d nn = pr.normal * pr.normal.transpose();
    const Eigen::Matrix3d B =
        scale_k * pr.stiffness * nn + scale_c * pr.eta * (Eigen::Matrix3d::Identity() - nn);
    for (int a = 0; a < 4; ++a) A->add_diagonal_block(nodes[a], c[a] * c[a] * B);
  }
}

double SelfContact::add(const Eigen::VectorXd& v, Eigen::VectorXd* f,
                        std::vector<Eigen::Triplet<double>>* trip, double scale_k,
                        double scale_c) {
  const double energy = add_forces(v, f);
  for (const Pair& pr : pairs_) {
    if (pr.stiffness == 0.0 && pr.eta == 0.0) continue;
    const int nodes[4] = {pr.vertex, pr.tri[0], pr.tri[1], pr.tri[2]};
    const double c[4] = {1.0, -pr.weights[0], -pr.weights[1], -pr.weights[2]};
    const Eigen::Matrix3d nn = pr.normal * pr.normal.transpose();
    const Eigen::Matrix3d B =
        scale_k * pr.stiffness * nn + scale_c * pr.eta * (Eigen::Matrix3d::Identity() - nn);
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) {
        const Eigen::Matrix3d Bab = c[a] * c[b] * B;
        for (int r = 0; r < 3; ++r) {
          for (int s = 0; s < 3; ++s)
            trip->emplace_back(3 * nodes[a] + r, 3 * nodes[b] + s, Bab(r, s));
        }
      }
    }
  }
  return energy;
}

}  // namespace mvtwin::forward
