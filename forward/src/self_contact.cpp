#include "mvtwin/forward/self_contact.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <unordered_map>

#include <Eigen/Geometry>
#include <unsupported/Eigen/AutoDiff>

#include "mvtwin/core/error.h"
#include "mvtwin/core/point_triangle_distance.h"
#include "mvtwin/core/units.h"
#include "run_both.h"
#include "uniform_grid.h"

namespace mvtwin::forward {
namespace {

/// Pairs whose nearest triangle lies up to this much beyond the alarm distance are kept while
/// the smooth distance is on (mm).
constexpr double kSmoothSlack = 0.3;

/// Squared distance between two points of the unrolled plane, periodic in x with `period`
/// (0: not periodic).
double plane_distance2(const Eigen::Vector2d& p, const Eigen::Vector2d& q, double period) {
  double dx = q.x() - p.x();
  if (period > 0 && std::abs(dx) > 0.5 * period) dx -= period * std::round(dx / period);
  const double dy = q.y() - p.y();
  return dx * dx + dy * dy;
}

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

/// The four nodes of a pair and the weights that map their motion to the vertex's motion
/// relative to its closest point on the triangle (J = [I, -w0 I, -w1 I, -w2 I]).
struct Stencil {
  int nodes[4];
  double c[4];
};
Stencil stencil(const SelfContact::Pair& pr) {
  return {{pr.vertex, pr.tri[0], pr.tri[1], pr.tri[2]},
          {1.0, -pr.weights[0], -pr.weights[1], -pr.weights[2]}};
}
/// scale_k x the pair's normal stiffness plus scale_c x its friction damping, as the 3x3 block
/// that J^T (.) J spreads over the four nodes.
Eigen::Matrix3d tangent_block(const SelfContact::Pair& pr, double scale_k, double scale_c) {
  const Eigen::Matrix3d nn = pr.normal * pr.normal.transpose();
  return scale_k * pr.stiffness * nn + scale_c * pr.eta * (Eigen::Matrix3d::Identity() - nn);
}

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
  std::map<int, int> plane_of_node;  // contact node -> plane index
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
        sub = {{nd[0], mid[0], mid[2]},
               {mid[0], nd[1], mid[1]},
               {mid[2], mid[1], nd[2]},
               {mid[0], mid[1], mid[2]}};
        sub_plane = {{pl[0], mpl[0], mpl[2]},
                     {mpl[0], pl[1], mpl[1]},
                     {mpl[2], mpl[1], pl[2]},
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
        // The model's triangles face the ventricle: outward on the ventricular surface, inward
        // (into the leaflet) on the atrial one.
        s.triangle_outward.push_back(layer == 0 ? -1 : 1);
      }
    }
  }
  for (const auto& [node, area] : area_of_node) {
    s.vertices.push_back(node);
    s.vertex_plane.push_back(plane_of_node.at(node));
    s.vertex_area.push_back(area);
  }
  s.plane.resize(static_cast<Eigen::Index>(plane.size()), 2);
  for (size_t i = 0; i < plane.size(); ++i)
    s.plane.row(static_cast<Eigen::Index>(i)) = plane[i].transpose();
  return s;
}

bool SelfContactOptions::is_valid(std::string* error) const {
  auto bad = [&](const char* m) {
    *error = m;
    return false;
  };
  if (!(alarm_mm > contact_mm && contact_mm >= 0 && alarm_mm <= 5))
    return bad("contact distances must satisfy 0 <= contact < alarm <= 5 mm");
  if (!(friction >= 0 && friction <= 5)) return bad("contact friction must be in [0, 5]");
  if (!(friction_slip_mm_per_s > 0)) return bad("contact friction slip must be positive");
  if (!(stiffness_factor >= 1 && stiffness_factor <= 1000))
    return bad("contact stiffness factor must be in [1, 1000]");
  if (!(wall_factor >= 0 && wall_factor <= 1e4))
    return bad("contact wall factor must be in [0, 1e4]");
  if (!(exclusion_mm >= 0 && margin_mm > 0))
    return bad("contact exclusion must be >= 0 and margin > 0 mm");
  if (!(ccd_depth_mm >= 0 && ccd_depth_mm <= contact_mm))
    return bad("contact_ccd_depth_mm must be in [0, contact distance]");
  if (!(smooth_mm >= 0 && smooth_mm <= 5)) return bad("contact_smooth_mm must be in [0, 5] mm");
  return true;
}

double SelfContactOptions::scaling_pressure_mpa(double peak_pressure_mpa) {
  return std::max(peak_pressure_mpa, units::mmhg_to_mpa(10.0));
}

double SelfContactOptions::stiffness_per_area(double peak_pressure_mpa) const {
  return stiffness_factor * scaling_pressure_mpa(peak_pressure_mpa) / (alarm_mm - contact_mm);
}

SelfContact::SelfContact(Surface surface, const SelfContactOptions& o, double stiffness_per_area,
                         double max_depth_mm)
    : opt_(o),
      stiffness_per_area_(stiffness_per_area),
      max_depth_mm_(max_depth_mm),
      s_(std::move(surface)) {
  if (std::string why; !o.is_valid(&why)) throw Error("self-contact: " + why);
  if (!(stiffness_per_area >= 0.0 && std::isfinite(stiffness_per_area) && max_depth_mm > 0.0))
    throw Error("self-contact: stiffness per area must be >= 0 and the maximum depth > 0");
  if (s_.vertices.size() != s_.vertex_plane.size() || s_.vertices.size() != s_.vertex_area.size() ||
      s_.triangles.size() != s_.triangle_plane.size() ||
      s_.triangles.size() != s_.triangle_outward.size() ||
      (!s_.triangle_group.empty() && s_.triangle_group.size() != s_.triangles.size())) {
    throw Error("self-contact: surface arrays differ in size");
  }
  for (const auto& tp : s_.triangle_plane) {
    Eigen::Vector2d corner[3];
    for (int k = 0; k < 3; ++k) {
      corner[k] = s_.plane.row(tp[k]).transpose();
      if (k > 0 && s_.period > 0)
        corner[k].x() -= s_.period * std::round((corner[k].x() - corner[0].x()) / s_.period);
    }
    const Eigen::Vector2d centre = (corner[0] + corner[1] + corner[2]) / 3.0;
    double radius = 0.0;
    for (const Eigen::Vector2d& c : corner) radius = std::max(radius, (c - centre).norm());
    const double slack = 1e-9 * (1.0 + opt_.exclusion_mm);
    const double inside = opt_.exclusion_mm - radius - slack,
                 outside = opt_.exclusion_mm + radius + slack;
    triangle_centre_.push_back(centre);
    triangle_inside2_.push_back(inside > 0 ? inside * inside : -1.0);
    triangle_outside2_.push_back(outside * outside);
  }
  for (int vp : s_.vertex_plane) vertex_uv_.push_back(s_.plane.row(vp).transpose());
  // Connectivity for the distances' signs at edges and corners.
  {
    std::map<std::pair<int, int>, std::vector<std::pair<int, int>>> edges;  // -> (triangle, k)
    for (size_t t = 0; t < s_.triangles.size(); ++t) {
      for (int k = 0; k < 3; ++k) {
        const int a = s_.triangles[t][k], b = s_.triangles[t][(k + 1) % 3];
        edges[{std::min(a, b), std::max(a, b)}].emplace_back(static_cast<int>(t), k);
        node_triangles_[a].push_back(static_cast<int>(t));
      }
    }
    edge_neighbour_.assign(s_.triangles.size(), {-1, -1, -1});
    for (const auto& [e, sides] : edges) {
      if (sides.size() == 2) {  // a manifold edge; more than two: left as boundary
        edge_neighbour_[sides[0].first][sides[0].second] = sides[1].first;
        edge_neighbour_[sides[1].first][sides[1].second] = sides[0].first;
      } else {
        node_on_boundary_.insert(e.first);
        node_on_boundary_.insert(e.second);
      }
    }
  }
  // Each group's corners around the mean of its triangles' centres (unrolled next to the first
  // one's; any centre is correct, a central one makes the test decide more vertices).
  for (size_t t0 = 0; t0 < s_.triangles.size(); t0 += kSearchGroup) {
    const size_t t1 = std::min(s_.triangles.size(), t0 + kSearchGroup);
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (size_t t = t0; t < t1; ++t) {
      Eigen::Vector2d ct = triangle_centre_[t];
      if (s_.period > 0)
        ct.x() -= s_.period * std::round((ct.x() - triangle_centre_[t0].x()) / s_.period);
      centre += ct / static_cast<double>(t1 - t0);
    }
    double radius2 = 0.0;
    for (size_t t = t0; t < t1; ++t) {
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector2d corner = s_.plane.row(s_.triangle_plane[t][k]).transpose();
        radius2 = std::max(radius2, plane_distance2(centre, corner, s_.period));
      }
    }
    const double inside = opt_.exclusion_mm - std::sqrt(radius2) - 1e-9 * (1.0 + opt_.exclusion_mm);
    group_centre_.push_back(centre);
    group_inside2_.push_back(inside > 0 ? inside * inside : -1.0);
  }
}

bool SelfContact::excluded(int i, int t) const {
  const Eigen::Vector2d& pv = vertex_uv_[i];
  // The corners lie within the radius of the centre (distances on the unrolled cylinder obey
  // the triangle inequality): most pairs are decided here, the rest corner by corner.
  const double centre2 = plane_distance2(pv, triangle_centre_[t], s_.period);
  if (centre2 < triangle_inside2_[t]) return true;
  if (centre2 > triangle_outside2_[t]) return false;
  const double limit2 = opt_.exclusion_mm * opt_.exclusion_mm;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector2d corner = s_.plane.row(s_.triangle_plane[t][k]).transpose();
    if (plane_distance2(pv, corner, s_.period) < limit2) return true;
  }
  return false;
}

void SelfContact::full_search(const Eigen::VectorXd& x) {
  ++searches_;
  candidates_.clear();
  const double reach = opt_.alarm_mm + opt_.margin_mm;
  // Vertices binned once in cells of size `reach`; each triangle visits the cells its box,
  // grown by `reach`, overlaps.
  const UniformGrid grid(static_cast<int>(s_.vertices.size()), reach,
                         [&](int i) { return Eigen::Vector3d(x.segment<3>(3 * s_.vertices[i])); });
  // What the loop below reads of each vertex, copied in the grid's slot order: a group's cells
  // are then read contiguously instead of through two indirections into x.
  struct Slot {
    Eigen::Vector3d p;
    Eigen::Vector2d uv;
    int vertex;
  };
  std::vector<Slot> slots;
  slots.reserve(grid.items().size());
  for (int i : grid.items()) slots.push_back({x.segment<3>(3 * s_.vertices[i]), vertex_uv_[i], i});
  // The triangles in groups of kSearchGroup (a quadratic face's four): one visit of the grid
  // (the cells of the group's box grown by `reach`), then one sphere test and one exclusion
  // test per vertex and group. Most vertices near a triangle are its neighbours on the leaflet
  // (the other surface of the same leaflet among them), excluded for the whole group at once;
  // the others are tested triangle by triangle. Spheres rather than boxes: a vertex within
  // `reach` of a triangle is within reach of the sphere around its corners, a tighter test than
  // the box (half its volume), with a slack far above round-off so that no pair the exact test
  // keeps is dropped.
  const double slack = 1e-9 * (1.0 + reach);
  auto search = [&](size_t g0, size_t g1, std::vector<Candidate>* found) {
    Eigen::Vector3d a[kSearchGroup], b[kSearchGroup], c[kSearchGroup], m[kSearchGroup];
    double r2[kSearchGroup];
    for (size_t g = g0; g < g1; ++g) {
      const size_t t0 = g * kSearchGroup, n = std::min(kSearchGroup, s_.triangles.size() - t0);
      Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
      Eigen::Vector3d hi = -lo;
      for (size_t k = 0; k < n; ++k) {
        const std::array<int, 3>& tri = s_.triangles[t0 + k];
        a[k] = x.segment<3>(3 * tri[0]);
        b[k] = x.segment<3>(3 * tri[1]);
        c[k] = x.segment<3>(3 * tri[2]);
        lo = lo.cwiseMin(a[k]).cwiseMin(b[k]).cwiseMin(c[k]);
        hi = hi.cwiseMax(a[k]).cwiseMax(b[k]).cwiseMax(c[k]);
      }
      const Eigen::Vector3d gm = 0.5 * (lo + hi);
      double gr = 0.0;
      for (size_t k = 0; k < n; ++k) {
        m[k] = (a[k] + b[k] + c[k]) / 3.0;
        const double r =
            std::sqrt(std::max({(a[k] - m[k]).squaredNorm(), (b[k] - m[k]).squaredNorm(),
                                (c[k] - m[k]).squaredNorm()})) +
            reach + slack;
        r2[k] = r * r;
        gr = std::max(gr, (m[k] - gm).norm() + r);
      }
      const double gr2 = gr * gr;
      lo.array() -= reach;
      hi.array() += reach;
      grid.for_each_slots_near(lo, hi, [&](int first, int last) {
        for (int q = first; q < last; ++q) {
          const Slot& v = slots[static_cast<size_t>(q)];
          if ((v.p - gm).squaredNorm() > gr2) continue;
          if (plane_distance2(v.uv, group_centre_[g], s_.period) < group_inside2_[g]) continue;
          for (size_t k = 0; k < n; ++k) {
            const int t = static_cast<int>(t0 + k);
            // excluded()'s first test inline (it decides most pairs), then excluded() itself.
            if ((v.p - m[k]).squaredNorm() > r2[k] ||
                plane_distance2(v.uv, triangle_centre_[t], s_.period) < triangle_inside2_[t] ||
                excluded(v.vertex, t))
              continue;
            const Eigen::Vector3d cp = closest_point_on_triangle(v.p, a[k], b[k], c[k]);
            if ((v.p - cp).norm() < reach) found->push_back({v.vertex, t});
          }
        }
      });
    }
  };
  const size_t ng = group_centre_.size();
  std::vector<Candidate> second;
  run_both(
      threads_, [&] { search(0, ng / 2, &candidates_); }, [&] { search(ng / 2, ng, &second); });
  candidates_.insert(candidates_.end(), second.begin(), second.end());
  // Grouped by vertex (detect() walks each vertex's candidates together), in a fixed order.
  std::sort(candidates_.begin(), candidates_.end(), [](const Candidate& p, const Candidate& q) {
    return p.vertex != q.vertex ? p.vertex < q.vertex : p.triangle < q.triangle;
  });
  x_search_ = x;
}

signed char SelfContact::feature_side(const Eigen::VectorXd& x, int t, const Eigen::Vector3d& w,
                                      const Eigen::Vector3d& p_minus_q) const {
  const auto outward_normal = [&](int tri) {
    const auto& T = s_.triangles[tri];
    const Eigen::Vector3d a = x.segment<3>(3 * T[0]), b = x.segment<3>(3 * T[1]),
                          c = x.segment<3>(3 * T[2]);
    return Eigen::Vector3d(s_.triangle_outward[tri] * (b - a).cross(c - a).normalized());
  };
  int zeros = 0, corner = 0, opposite = 0;
  for (int k = 0; k < 3; ++k) {
    if (w[k] <= 1e-9) {
      ++zeros;
      opposite = k;
    } else {
      corner = k;
    }
  }
  Eigen::Vector3d pseudo = Eigen::Vector3d::Zero();
  if (zeros == 1) {
    // The edge opposite corner `opposite`: edge k = opposite + 1 joins corners k and k + 1.
    const int across = edge_neighbour_[t][(opposite + 1) % 3];
    if (across < 0) return 1;
    pseudo = outward_normal(t) + outward_normal(across);
  } else {
    const int node = s_.triangles[t][corner];
    if (node_on_boundary_.contains(node)) return 1;
    const Eigen::Vector3d v = x.segment<3>(3 * node);
    for (int tri : node_triangles_.at(node)) {
      const auto& T = s_.triangles[tri];
      const int j = T[0] == node ? 0 : T[1] == node ? 1 : 2;
      const Eigen::Vector3d e1 = x.segment<3>(3 * T[(j + 1) % 3]) - v,
                            e2 = x.segment<3>(3 * T[(j + 2) % 3]) - v;
      const double angle = std::atan2(e1.cross(e2).norm(), e1.dot(e2));
      pseudo += angle * outward_normal(tri);
    }
  }
  return p_minus_q.dot(pseudo) < 0.0 ? -1 : 1;
}

void SelfContact::closest_pairs(const Eigen::VectorXd& x, size_t k0, size_t k1,
                                std::vector<Pair>* pairs, double* min_distance) const {
  // Closest candidate triangle per vertex and triangle group.
  size_t k = k0;
  while (k < k1) {
    const int i = candidates_[k].vertex;
    const Eigen::Vector3d p = x.segment<3>(3 * s_.vertices[i]);
    std::array<Pair, 2> best{};
    for (Pair& b : best) b.distance = std::numeric_limits<double>::infinity();
    std::array<double, 2> best_len{best[0].distance, best[1].distance};
    for (; k < k1 && candidates_[k].vertex == i; ++k) {
      const int t = candidates_[k].triangle;
      const int g = s_.triangle_group.empty() ? 0 : (s_.triangle_group[t] != 0);
      const Eigen::Vector3d a = x.segment<3>(3 * s_.triangles[t][0]),
                            b = x.segment<3>(3 * s_.triangles[t][1]),
                            c = x.segment<3>(3 * s_.triangles[t][2]);
      const Eigen::Vector3d q = closest_point_on_triangle(p, a, b, c);
      const double len = (p - q).norm();
      // Only a nearer triangle than the best so far can answer: the rest (most candidates) is
      // decided by the unsigned distance alone, before the sign is worked out.
      if (!(len < best_len[g])) continue;
      const Eigen::Vector3d w = barycentric(q, a, b, c);
      // Over the face: the distance signed by the face's outward side (negative inside the
      // leaflet), so that a vertex pushed in is pushed back out; deeper than max_depth the
      // leaflet's other face is nearer and answers. Beyond an edge or a corner the distance is
      // signed by that feature's pseudo-normal (feature_side): a vertex sunk in under a valley
      // between two faces, where neither face is under it, is inside too, and is pushed out (the
      // plain distance pushed it in). The closest triangle is the one nearest the vertex (the
      // unsigned distance), so that a far triangle's corner below an inside vertex does not answer
      // for the face over it.
      Eigen::Vector3d n;
      double d;
      if (w.minCoeff() > 1e-9) {
        n = s_.triangle_outward[t] * (b - a).cross(c - a).normalized();
        d = n.dot(p - q);
      } else {
        // side x len keeps the sign at len = 0 (-0.0), from which linearize_exact reads it.
        d = feature_side(x, t, w, p - q) * len;
        n = len > 1e-12
                ? Eigen::Vector3d((p - q) / d)
                : Eigen::Vector3d(s_.triangle_outward[t] * (b - a).cross(c - a).normalized());
      }
      if (d < -max_depth_mm_) continue;
      best_len[g] = len;
      best[g].distance = d;
      best[g].vertex = s_.vertices[i];
      best[g].tri = s_.triangles[t];
      best[g].weights = w;
      best[g].triangle = t;
      best[g].vertex_area = s_.vertex_area[i];
      best[g].surface_vertex = i;
      best[g].normal = n;
      best[g].outward = s_.triangle_outward[t];
      best[g].area = 0.5 * (b - a).cross(c - a).norm();
    }
    for (Pair& b : best) {
      *min_distance = std::min(*min_distance, b.distance);
      // The smooth distance may be below the alarm distance where the nearest triangle's is
      // a little above it (a vertex over a valley): such pairs are kept too, their energy
      // from the smooth distance alone.
      if (b.distance < opt_.alarm_mm + (smooth_ ? kSmoothSlack : 0.0)) {
        // A free-edge vertex pressed edge-on against a face stands for little area of its own;
        // the face it presses on carries the load, so the larger of the two areas sets k.
        b.area_from_triangle = b.area >= s_.vertex_area[i];
        b.area = std::max(b.area, s_.vertex_area[i]);
        pairs->push_back(b);
      }
    }
  }
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
  if (smooth_) x_detect_ = x;
  // The candidates in two parts split between vertices (run_both), each vertex's pairs in
  // candidate order: the same pairs in the same order as one pass.
  size_t mid = candidates_.size() / 2;
  while (mid > 0 && mid < candidates_.size() &&
         candidates_[mid].vertex == candidates_[mid - 1].vertex)
    ++mid;
  std::vector<Pair> second;
  double min_first = std::numeric_limits<double>::infinity(), min_second = min_first;
  pairs_.clear();
  run_both(
      threads_, [&] { closest_pairs(x, 0, mid, &pairs_, &min_first); },
      [&] { closest_pairs(x, mid, candidates_.size(), &second, &min_second); });
  pairs_.insert(pairs_.end(), second.begin(), second.end());
  min_distance_ = std::min(min_first, min_second);
  return static_cast<int>(pairs_.size());
}

namespace {

/// Whether p passes into the solid through triangle (a, b, c), deeper than `depth`, as all four
/// move linearly from t = 0 to 1: a root of g(t), p's signed distance from the triangle's plane
/// moved `depth` inwards (positive outside; `outward` is +1 when (b - a) x (c - a) points out),
/// where p lies over the triangle, with p ending deeper than `depth` on the inner side. A vertex
/// that had sunk slightly in and comes back out is not a crossing, nor is one that ends less
/// than `depth` in: the contact law pushes it back out (with depth 0, every pass is one).
bool vertex_triangle_crossing(const Eigen::Vector3d p[2], const Eigen::Vector3d a[2],
                              const Eigen::Vector3d b[2], const Eigen::Vector3d c[2], int outward,
                              double depth) {
  auto at = [](const Eigen::Vector3d q[2], double t) {
    return Eigen::Vector3d((1 - t) * q[0] + t * q[1]);
  };
  auto f = [&](double t) {
    const Eigen::Vector3d A = at(a, t);
    const Eigen::Vector3d n = (at(b, t) - A).cross(at(c, t) - A);
    const double plane = n.dot(at(p, t) - A);
    // depth 0: the coplanarity cubic itself (no division, exact for a degenerate triangle).
    return depth > 0 ? outward * plane / n.norm() + depth : outward * plane;
  };
  auto inside = [&](double t) {
    const Eigen::Vector3d A = at(a, t), B = at(b, t), C = at(c, t), P = at(p, t);
    const Eigen::Vector3d w = barycentric(P, A, B, C);
    const double tol = 1e-6;
    return w.minCoeff() >= -tol &&
           (P - (w[0] * A + w[1] * B + w[2] * C)).norm() < depth + 1e-6 + 1e-3 * (B - A).norm();
  };
  // g is a cubic (depth 0) or a cubic over a smooth positive norm plus a constant: sample
  // finely enough to separate its roots on valve-scale motion, then bisect each sign change.
  constexpr int kSamples = 16;
  if (!(f(1.0) < 0)) return false;  // ends outside, or less than `depth` in
  double t0 = 0.0, f0 = f(0.0);
  if (f0 == 0.0 && inside(0.0)) return true;
  for (int k = 1; k <= kSamples; ++k) {
    const double t1 = static_cast<double>(k) / kSamples, f1 = f(t1);
    if (f1 == 0.0 && inside(t1)) return true;
    if ((f0 < 0) != (f1 < 0)) {
      double lo = t0, hi = t1, flo = f0;
      for (int it = 0; it < 40; ++it) {
        const double mid = 0.5 * (lo + hi), fm = f(mid);
        if ((fm < 0) == (flo < 0)) {
          lo = mid;
          flo = fm;
        } else {
          hi = mid;
        }
      }
      if (inside(0.5 * (lo + hi))) return true;
    }
    t0 = t1;
    f0 = f1;
  }
  return false;
}

}  // namespace

int SelfContact::find_crossing(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1) const {
  // Motion of the contact vertices since the last search, at both ends of the step.
  double since_search = std::numeric_limits<double>::infinity(), step_motion = 0.0;
  if (x_search_.size() == x0.size()) {
    since_search = 0.0;
    for (int v : s_.vertices) {
      since_search =
          std::max({since_search, (x0.segment<3>(3 * v) - x_search_.segment<3>(3 * v)).norm(),
                    (x1.segment<3>(3 * v) - x_search_.segment<3>(3 * v)).norm()});
    }
  }
  for (int v : s_.vertices)
    step_motion = std::max(step_motion, (x1.segment<3>(3 * v) - x0.segment<3>(3 * v)).norm());
  // Never as deep as the leaflet's other face answers (max_depth_mm_), where the law would push
  // the vertex on through.
  const double depth = std::min(opt_.ccd_depth_mm, 0.5 * max_depth_mm_);
  auto test = [&](int i, int t) {
    const int v = s_.vertices[i];
    const auto& tri = s_.triangles[t];
    const Eigen::Vector3d p[2] = {x0.segment<3>(3 * v), x1.segment<3>(3 * v)};
    const Eigen::Vector3d a[2] = {x0.segment<3>(3 * tri[0]), x1.segment<3>(3 * tri[0])};
    const Eigen::Vector3d b[2] = {x0.segment<3>(3 * tri[1]), x1.segment<3>(3 * tri[1])};
    const Eigen::Vector3d c[2] = {x0.segment<3>(3 * tri[2]), x1.segment<3>(3 * tri[2])};
    return vertex_triangle_crossing(p, a, b, c, s_.triangle_outward[t], depth);
  };
  // Two halves at once (run_both): the first crossing of the first half, else of the second,
  // is the first crossing in order.
  int found[2] = {-1, -1};
  if (since_search < 0.5 * opt_.margin_mm) {
    auto scan = [&](size_t k0, size_t k1, int* first) {
      for (size_t k = k0; k < k1; ++k) {
        if (test(candidates_[k].vertex, candidates_[k].triangle)) {
          *first = s_.vertices[candidates_[k].vertex];
          return;
        }
      }
    };
    const size_t nc = candidates_.size();
    run_both(
        threads_, [&] { scan(0, nc / 2, &found[0]); }, [&] { scan(nc / 2, nc, &found[1]); });
    return found[0] >= 0 ? found[0] : found[1];
  }
  // Swept boxes: every vertex's segment against every triangle's box over the step, in a grid.
  const double h = std::max(opt_.alarm_mm + opt_.margin_mm, 2.0 * step_motion);
  const UniformGrid grid(static_cast<int>(s_.vertices.size()), h, [&](int i) {
    return Eigen::Vector3d(0.5 *
                           (x0.segment<3>(3 * s_.vertices[i]) + x1.segment<3>(3 * s_.vertices[i])));
  });
  auto sweep = [&](size_t t0, size_t t1, int* first) {
    for (size_t t = t0; t < t1; ++t) {
      const auto& tri = s_.triangles[t];
      Eigen::Vector3d lo = x0.segment<3>(3 * tri[0]), hi = lo;
      for (int k = 0; k < 3; ++k) {
        for (const Eigen::VectorXd* x : {&x0, &x1}) {
          lo = lo.cwiseMin(x->segment<3>(3 * tri[k]));
          hi = hi.cwiseMax(x->segment<3>(3 * tri[k]));
        }
      }
      // A crossing point lies on the vertex's segment and within `depth` of the triangle, so in
      // both boxes (grown by depth and more than the crossing test's tolerance, 1e-3 x an edge +
      // 1e-6 mm).
      const double slack = 1e-2 + depth + 1e-3 * (hi - lo).norm();
      const Eigen::Vector3d reach_lo = lo.array() - slack, reach_hi = hi.array() + slack;
      // A vertex's segment midpoint is within step_motion / 2 of every point of it.
      lo.array() -= 0.5 * step_motion + 1e-9;
      hi.array() += 0.5 * step_motion + 1e-9;
      grid.for_each_near(lo, hi, [&](int i) {
        const int v = s_.vertices[i];
        if (*first >= 0 || v == tri[0] || v == tri[1] || v == tri[2]) return;
        const Eigen::Vector3d p0 = x0.segment<3>(3 * v), p1 = x1.segment<3>(3 * v);
        if ((p0.cwiseMax(p1).array() < reach_lo.array()).any() ||
            (p0.cwiseMin(p1).array() > reach_hi.array()).any())
          return;
        if (!excluded(i, static_cast<int>(t)) && test(i, static_cast<int>(t))) *first = v;
      });
      if (*first >= 0) return;
    }
  };
  const size_t nt = s_.triangles.size();
  run_both(
      threads_, [&] { sweep(0, nt / 2, &found[0]); }, [&] { sweep(nt / 2, nt, &found[1]); });
  return found[0] >= 0 ? found[0] : found[1];
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

bool SelfContact::gather_smooth(const Pair& pr, const Eigen::VectorXd& x, SmoothSet* set) const {
  set->nodes.clear();
  set->tris.clear();
  set->outward.clear();
  set->edges.clear();
  set->K.resize(0, 0);
  if (pr.triangle < 0) return false;
  const double h = opt_.smooth_mm;
  const Eigen::Vector3d p = x.segment<3>(3 * pr.vertex);
  const auto centre = [&](int t) {
    const auto& T = s_.triangles[t];
    return Eigen::Vector3d(
        (x.segment<3>(3 * T[0]) + x.segment<3>(3 * T[1]) + x.segment<3>(3 * T[2])) / 3.0);
  };
  // The triangles around the nearest one, over the surface's edges, whose centres lie within
  // the kernel (h), walking on through triangles up to 2 h away so that a kernel cut by a
  // long triangle still finds the ones beyond it; only the nearest triangle's group, and not
  // the vertex's own neighbours (fixed subsets of the surface: the distance stays smooth).
  const auto group = [&](int t) {
    return s_.triangle_group.empty() ? 0 : static_cast<int>(s_.triangle_group[t] != 0);
  };
  const int g0 = group(pr.triangle);
  std::vector<int> found{pr.triangle}, queue{pr.triangle}, walked;
  std::unordered_set<int> seen{pr.triangle};
  while (!queue.empty()) {
    const int t = queue.back();
    queue.pop_back();
    walked.push_back(t);
    for (int across : edge_neighbour_[t]) {
      if (across < 0 || group(across) != g0 || !seen.insert(across).second) continue;
      const double r = (centre(across) - p).norm();
      if (r > 2.0 * h) continue;
      queue.push_back(across);
      if (r < h && !excluded(pr.surface_vertex, across)) found.push_back(across);
    }
  }
  std::unordered_map<int, int> local;
  set->nodes.push_back(pr.vertex);
  local[pr.vertex] = 0;
  const auto local_index = [&](int node) {
    auto [it, fresh] = local.emplace(node, static_cast<int>(set->nodes.size()));
    if (fresh) set->nodes.push_back(node);
    return it->second;
  };
  for (int t : found) {
    if ((centre(t) - p).squaredNorm() >= h * h) continue;
    std::array<int, 3> lt{};
    for (int k = 0; k < 3; ++k) lt[k] = local_index(s_.triangles[t][k]);
    set->tris.push_back(lt);
    set->outward.push_back(s_.triangle_outward[t]);
  }
  // The surface's boundary edges whose midpoints lie within the kernel.
  for (int t : walked) {
    if (excluded(pr.surface_vertex, t)) continue;
    const auto& T = s_.triangles[t];
    for (int k = 0; k < 3; ++k) {
      if (edge_neighbour_[t][k] >= 0) continue;
      const int na = T[k], nb = T[(k + 1) % 3], nc = T[(k + 2) % 3];
      const Eigen::Vector3d mid = 0.5 * (x.segment<3>(3 * na) + x.segment<3>(3 * nb));
      if ((mid - p).squaredNorm() >= h * h) continue;
      set->edges.push_back({local_index(na), local_index(nb), local_index(nc)});
    }
  }
  if (set->tris.empty()) {  // no triangle's centre within the kernel: the nearest's distance
    set->nodes.clear();
    set->outward.clear();
    set->edges.clear();
    return false;
  }
  set->vertex_area = pr.vertex_area;
  return true;
}

namespace {
using Vec12 = Eigen::Matrix<double, 12, 1>;
using Mat12 = Eigen::Matrix<double, 12, 12>;
using AD12 = Eigen::AutoDiffScalar<Vec12>;

/// The kernel psi(u) = (1 - u)^3 for u = r^2 / h^2 < 1 (twice differentiable at u = 1).
template <class S>
S kernel(const S& u) {
  const S v = S(1.0) - u;
  return v * v * v;
}

/// One triangle's sums (p, a, b, c in Y): its weight w = A psi, w times the signed distance of p
/// to its plane, w times its area A. Zero outside the kernel.
template <class S>
void triangle_terms(const Eigen::Matrix<S, 12, 1>& Y, double outward, double h, S out[3]) {
  using std::sqrt;
  using V3 = Eigen::Matrix<S, 3, 1>;
  const V3 p = Y.template segment<3>(0), a = Y.template segment<3>(3), b = Y.template segment<3>(6),
           c = Y.template segment<3>(9);
  const V3 cr = (b - a).cross(c - a);
  const S twice_area = sqrt(cr.squaredNorm());
  const V3 ctr = (a + b + c) / S(3.0);
  const S u = (p - ctr).squaredNorm() / S(h * h);
  if (!(u < S(1.0)) || !(twice_area > S(0.0))) {
    out[0] = out[1] = out[2] = S(0.0);
    return;
  }
  const S area = S(0.5) * twice_area;
  const S w = area * kernel(u);
  out[0] = w;
  out[1] = w * (S(outward) / twice_area) * cr.dot(p - ctr);
  out[2] = w * area;
}

/// One boundary edge's sums (p, a, b and the third corner c in Y): its weight w = |b - a| psi
/// and w times the distance of p beyond the edge, along the direction in the triangle's plane
/// that points away from c.
template <class S>
void edge_terms(const Eigen::Matrix<S, 12, 1>& Y, double h, S out[2]) {
  using std::sqrt;
  using V3 = Eigen::Matrix<S, 3, 1>;
  const V3 p = Y.template segment<3>(0), a = Y.template segment<3>(3), b = Y.template segment<3>(6),
           c = Y.template segment<3>(9);
  const V3 e = b - a, mid = (a + b) / S(2.0);
  const V3 n = e.cross(c - a);
  V3 m = n.cross(e);  // in the plane, perpendicular to the edge, towards c
  const S len = sqrt(e.squaredNorm()), mlen = sqrt(m.squaredNorm());
  const S u = (p - mid).squaredNorm() / S(h * h);
  if (!(u < S(1.0)) || !(mlen > S(0.0))) {
    out[0] = out[1] = S(0.0);
    return;
  }
  const S w = len * kernel(u);
  out[0] = w;
  out[1] = -w * m.dot(p - mid) / mlen;
}

/// Values, gradients and Hessians (central differences of the exact gradient) of K sums.
template <int K, class F>
void local_terms(const Vec12& Y, F&& f, bool with_hessian, double v[K], Vec12 g[K], Mat12 H[K]) {
  Eigen::Matrix<AD12, 12, 1> Ya;
  const auto eval = [&](const Vec12& Z, AD12 out[K]) {
    for (int i = 0; i < 12; ++i) Ya[i] = AD12(Z[i], 12, i);
    f(Ya, out);
  };
  AD12 out[K];
  eval(Y, out);
  for (int k = 0; k < K; ++k) {
    v[k] = out[k].value();
    g[k] = out[k].derivatives().size() == 12 ? Vec12(out[k].derivatives()) : Vec12::Zero();
  }
  if (!with_hessian) return;
  if (v[0] == 0.0) {
    for (int k = 0; k < K; ++k) H[k].setZero();
    return;
  }
  constexpr double eps = 1e-6;
  for (int j = 0; j < 12; ++j) {
    Vec12 Zp = Y, Zm = Y;
    Zp[j] += eps;
    Zm[j] -= eps;
    AD12 op[K], om[K];
    eval(Zp, op);
    eval(Zm, om);
    for (int k = 0; k < K; ++k) {
      const Vec12 gp =
          op[k].derivatives().size() == 12 ? Vec12(op[k].derivatives()) : Vec12::Zero();
      const Vec12 gm =
          om[k].derivatives().size() == 12 ? Vec12(om[k].derivatives()) : Vec12::Zero();
      H[k].col(j) = (gp - gm) / (2 * eps);
    }
  }
  for (int k = 0; k < K; ++k) H[k] = (0.5 * (H[k] + H[k].transpose())).eval();
}

/// A ratio q = N / D of sums with their gradients and Hessians: q, grad q, Hess q.
void ratio(double N, double D, const Eigen::VectorXd& gN, const Eigen::VectorXd& gD,
           const Eigen::MatrixXd* HN, const Eigen::MatrixXd* HD, double* q, Eigen::VectorXd* gq,
           Eigen::MatrixXd* Hq) {
  *q = N / D;
  *gq = (gN - *q * gD) / D;
  if (Hq) *Hq = (*HN - *q * *HD - *gq * gD.transpose() - gD * gq->transpose()) / D;
}
}  // namespace

double SelfContact::smooth_energy(const SmoothSet& set, const Eigen::VectorXd& X,
                                  Eigen::VectorXd* gradient, Eigen::MatrixXd* hessian,
                                  double* distance) const {
  const double h = opt_.smooth_mm;
  const Eigen::Index n = X.size();
  const bool want_h = hessian != nullptr;
  // The sums over the kernel's triangles (W, F, AA) and boundary edges (WE, G).
  double sum[5] = {0, 0, 0, 0, 0};
  std::vector<Eigen::VectorXd> grad(5, Eigen::VectorXd::Zero(n));
  std::vector<Eigen::MatrixXd> hess(want_h ? 5 : 0, Eigen::MatrixXd::Zero(n, n));
  const auto scatter = [&](const std::array<int, 4>& idx, int which, double v, const Vec12& g,
                           const Mat12& H) {
    sum[which] += v;
    for (int a = 0; a < 4; ++a) {
      grad[which].segment<3>(3 * idx[a]) += g.segment<3>(3 * a);
      if (!want_h) continue;
      for (int b = 0; b < 4; ++b)
        hess[which].block<3, 3>(3 * idx[a], 3 * idx[b]) += H.block<3, 3>(3 * a, 3 * b);
    }
  };
  for (size_t t = 0; t < set.tris.size(); ++t) {
    const std::array<int, 4> idx{0, set.tris[t][0], set.tris[t][1], set.tris[t][2]};
    Vec12 Y;
    for (int a = 0; a < 4; ++a) Y.segment<3>(3 * a) = X.segment<3>(3 * idx[a]);
    double v[3];
    Vec12 g[3];
    Mat12 H[3];
    const double out = set.outward[t];
    local_terms<3>(
        Y, [&](const Eigen::Matrix<AD12, 12, 1>& Z, AD12 o[3]) { triangle_terms(Z, out, h, o); },
        want_h, v, g, H);
    for (int k = 0; k < 3; ++k) scatter(idx, k, v[k], g[k], H[k]);
  }
  for (const auto& e : set.edges) {
    const std::array<int, 4> idx{0, e[0], e[1], e[2]};
    Vec12 Y;
    for (int a = 0; a < 4; ++a) Y.segment<3>(3 * a) = X.segment<3>(3 * idx[a]);
    double v[2];
    Vec12 g[2];
    Mat12 H[2];
    local_terms<2>(
        Y, [&](const Eigen::Matrix<AD12, 12, 1>& Z, AD12 o[2]) { edge_terms(Z, h, o); }, want_h, v,
        g, H);
    for (int k = 0; k < 2; ++k) scatter(idx, 3 + k, v[k], g[k], H[k]);
  }
  if (gradient) gradient->setZero(n);
  if (hessian) hessian->setZero(n, n);
  if (!(sum[0] > 0.0)) {
    *distance = std::numeric_limits<double>::infinity();
    return 0.0;
  }
  // f: the kernel's mean plane distance; A: its mean triangle area; g: the mean distance
  // beyond the boundary's edges.
  double f, A, g = 0.0;
  Eigen::VectorXd gf, gA, gg = Eigen::VectorXd::Zero(n);
  Eigen::MatrixXd Hf, HA, Hg;
  ratio(sum[1], sum[0], grad[1], grad[0], want_h ? &hess[1] : nullptr, want_h ? &hess[0] : nullptr,
        &f, &gf, want_h ? &Hf : nullptr);
  ratio(sum[2], sum[0], grad[2], grad[0], want_h ? &hess[2] : nullptr, want_h ? &hess[0] : nullptr,
        &A, &gA, want_h ? &HA : nullptr);
  if (sum[3] > 0.0)
    ratio(sum[4], sum[3], grad[4], grad[3], want_h ? &hess[4] : nullptr,
          want_h ? &hess[3] : nullptr, &g, &gg, want_h ? &Hg : nullptr);
  // The distance: f over the surface; beyond its boundary (g > 0) sqrt(f^2 + g^2), positive.
  double d = f, df = 1.0, dg = 0.0, dff = 0.0, dfg = 0.0, dgg = 0.0;
  const bool beyond = g > 0.0;
  if (beyond) {
    d = std::sqrt(f * f + g * g);
    df = f / d;
    dg = g / d;
    const double d3 = d * d * d;
    dff = g * g / d3;
    dgg = f * f / d3;
    dfg = -f * g / d3;
  }
  *distance = d;
  const double da = opt_.alarm_mm, dc = opt_.contact_mm;
  if (d >= da) return 0.0;
  double phi = 0.5 * (da - d) * (da - d), phi1 = -(da - d), phi2 = 1.0;
  if (d < dc && dc > 0) {
    const double kw = opt_.wall_factor / dc, e = dc - d;
    phi += kw * e * e * e / 6.0;
    phi1 -= 0.5 * kw * e * e;
    phi2 += kw * e;
  }
  // k = stiffness per area x the larger of the vertex's and the kernel's mean area (smoothly).
  const double Av = set.vertex_area, D = A - Av, eps = 0.05 * Av, sD = std::sqrt(D * D + eps * eps);
  const double area = 0.5 * (A + Av + sD), area1 = 0.5 * (1.0 + D / sD),
               area2 = 0.5 * eps * eps / (sD * sD * sD);
  const double k = stiffness_per_area_ * area, k1 = stiffness_per_area_ * area1,
               k2 = stiffness_per_area_ * area2;
  const double E = k * phi;
  const double Ef = k * phi1 * df, Eg = k * phi1 * dg, EA = k1 * phi;
  if (gradient) *gradient = Ef * gf + Eg * gg + EA * gA;
  if (hessian) {
    const double Eff = k * (phi2 * df * df + phi1 * dff), Egg = k * (phi2 * dg * dg + phi1 * dgg),
                 Efg = k * (phi2 * df * dg + phi1 * dfg), EfA = k1 * phi1 * df,
                 EgA = k1 * phi1 * dg, EAA = k2 * phi;
    Eigen::MatrixXd& Hm = *hessian;
    Hm = Ef * Hf + EA * HA + Eff * gf * gf.transpose() + EAA * gA * gA.transpose() +
         EfA * (gf * gA.transpose() + gA * gf.transpose());
    if (beyond)
      Hm += Eg * Hg + Egg * gg * gg.transpose() +
            Efg * (gf * gg.transpose() + gg * gf.transpose()) +
            EgA * (gg * gA.transpose() + gA * gg.transpose());
  }
  return E;
}

double SelfContact::add_forces(const Eigen::VectorXd& v, Eigen::VectorXd* f) {
  double energy = 0.0;
  const double da = opt_.alarm_mm, dc = opt_.contact_mm;
  smooth_sets_.assign(smooth_ ? pairs_.size() : 0, SmoothSet{});
  for (size_t i = 0; i < pairs_.size(); ++i) {
    Pair& pr = pairs_[i];
    pr.force = pr.stiffness = pr.eta = 0.0;
    if (smooth_ && gather_smooth(pr, x_detect_, &smooth_sets_[i])) {
      // The smooth distance (at rest: no friction): the force is minus the energy's gradient.
      const SmoothSet& set = smooth_sets_[i];
      Eigen::VectorXd X(3 * set.nodes.size()), g;
      for (size_t a = 0; a < set.nodes.size(); ++a)
        X.segment<3>(3 * static_cast<Eigen::Index>(a)) = x_detect_.segment<3>(3 * set.nodes[a]);
      double d = 0.0;
      energy += smooth_energy(set, X, &g, nullptr, &d);
      for (size_t a = 0; a < set.nodes.size(); ++a)
        f->segment<3>(3 * set.nodes[a]) -= g.segment<3>(3 * static_cast<Eigen::Index>(a));
      // For the preconditioner's diagonal blocks: the law's stiffness at the pair's own
      // distance along its normal.
      law(pr.distance, stiffness_per_area_ * pr.area, &pr.force, &pr.stiffness);
      pr.force = 0.0;
      continue;
    }
    if (pr.distance >= da) continue;

    const double k = stiffness_per_area_ * pr.area;
    law(pr.distance, k, &pr.force, &pr.stiffness);
    energy += 0.5 * k * (da - pr.distance) * (da - pr.distance);
    if (pr.distance < dc && dc > 0) {
      energy += opt_.wall_factor * k * std::pow(dc - pr.distance, 3) / (6.0 * dc);
    }
    const Stencil st = stencil(pr);
    const Eigen::Vector3d& n = pr.normal;
    // Normal force pushes the vertex away from the triangle (and the triangle back).
    for (int a = 0; a < 4; ++a) f->segment<3>(3 * st.nodes[a]) += st.c[a] * pr.force * n;
    // Lagged Coulomb friction on the relative tangential velocity.
    Eigen::Vector3d vrel = Eigen::Vector3d::Zero();
    for (int a = 0; a < 4; ++a) vrel += st.c[a] * v.segment<3>(3 * st.nodes[a]);
    const Eigen::Vector3d vt = vrel - n * n.dot(vrel);
    pr.eta = opt_.friction * pr.force / std::max(vt.norm(), opt_.friction_slip_mm_per_s);
    for (int a = 0; a < 4; ++a) f->segment<3>(3 * st.nodes[a]) -= st.c[a] * pr.eta * vt;
  }
  return energy;
}

void SelfContact::multiply(const Eigen::VectorXd& p, double scale_k, double scale_c,
                           Eigen::VectorXd* y) const {
  for (size_t i = 0; i < pairs_.size(); ++i) {
    const Pair& pr = pairs_[i];
    if (pr.stiffness == 0.0 && pr.eta == 0.0) continue;
    if (i < smooth_sets_.size() && !smooth_sets_[i].nodes.empty()) continue;
    const Stencil st = stencil(pr);
    Eigen::Vector3d jp = Eigen::Vector3d::Zero();
    for (int a = 0; a < 4; ++a) jp += st.c[a] * p.segment<3>(3 * st.nodes[a]);
    const Eigen::Vector3d t = tangent_block(pr, scale_k, scale_c) * jp;
    for (int a = 0; a < 4; ++a) y->segment<3>(3 * st.nodes[a]) += st.c[a] * t;
  }
}

namespace {
// grad d of a vertex p over triangle (a, b, c) (12 entries: p, a, b, c), with the distance's
// definition of closest_pairs(): signed by the face's outward side over the face, beyond an
// edge or a corner the plain distance times `side`, the sign the pair's distance has (it does not
// change under the difference's 1e-6 mm).
Eigen::Matrix<double, 12, 1> distance_gradient(const Eigen::Matrix<double, 12, 1>& X,
                                               signed char outward, signed char side) {
  const Eigen::Vector3d p = X.segment<3>(0), a = X.segment<3>(3), b = X.segment<3>(6),
                        c = X.segment<3>(9);
  const Eigen::Vector3d q = closest_point_on_triangle(p, a, b, c);
  const Eigen::Vector3d w = barycentric(q, a, b, c);
  Eigen::Vector3d n;
  if (w.minCoeff() > 1e-9) {
    n = outward * (b - a).cross(c - a).normalized();
  } else {
    const double len = (p - q).norm();
    n = len > 1e-12 ? Eigen::Vector3d(side * (p - q) / len)
                    : Eigen::Vector3d(outward * (b - a).cross(c - a).normalized());
  }
  Eigen::Matrix<double, 12, 1> g;
  g << n, -w[0] * n, -w[1] * n, -w[2] * n;
  return g;
}
}  // namespace

void SelfContact::linearize_exact(const Eigen::VectorXd& x) {
  exact_.resize(pairs_.size());
  constexpr double eps = 1e-6;  // mm
  for (size_t i = 0; i < pairs_.size(); ++i) {
    const Pair& pr = pairs_[i];
    Eigen::Matrix<double, 12, 12>& K = exact_[i];
    K.setZero();
    if (i < smooth_sets_.size() && !smooth_sets_[i].nodes.empty()) {
      // The smooth distance: the energy's Hessian, central differences of its exact gradient.
      SmoothSet& set = smooth_sets_[i];
      const Eigen::Index n = 3 * static_cast<Eigen::Index>(set.nodes.size());
      Eigen::VectorXd X(n);
      for (size_t a = 0; a < set.nodes.size(); ++a)
        X.segment<3>(3 * static_cast<Eigen::Index>(a)) = x.segment<3>(3 * set.nodes[a]);
      Eigen::VectorXd g;
      double d = 0.0;
      smooth_energy(set, X, &g, &set.K, &d);
      set.K = (0.5 * (set.K + set.K.transpose())).eval();
      continue;
    }
    if (pr.stiffness == 0.0 && pr.force == 0.0) continue;
    const int nodes[4] = {pr.vertex, pr.tri[0], pr.tri[1], pr.tri[2]};
    Eigen::Matrix<double, 12, 1> X;
    for (int a = 0; a < 4; ++a) X.segment<3>(3 * a) = x.segment<3>(3 * nodes[a]);
    const signed char side = std::signbit(pr.distance) ? -1 : 1;
    const Eigen::Matrix<double, 12, 1> g = distance_gradient(X, pr.outward, side);
    Eigen::Matrix<double, 12, 12> hess;
    for (int j = 0; j < 12; ++j) {
      Eigen::Matrix<double, 12, 1> Xp = X, Xm = X;
      Xp[j] += eps;
      Xm[j] -= eps;
      hess.col(j) =
          (distance_gradient(Xp, pr.outward, side) - distance_gradient(Xm, pr.outward, side)) /
          (2 * eps);
    }
    // f = F(d) grad d, dF/dd = -stiffness: K = -df/dx = stiffness g g^T - F hess d.
    K = pr.stiffness * g * g.transpose() - pr.force * 0.5 * (hess + hess.transpose());
    if (pr.area_from_triangle && pr.area > 0) {
      // F is proportional to k = stiffness_per_area x the triangle's area A: the term
      // -(F / A) g grad A^T, with grad A = N/2 x (c - b), N/2 x (a - c), N/2 x (b - a) (N the
      // unit normal) over the triangle's corners.
      const Eigen::Vector3d a = X.segment<3>(3), b = X.segment<3>(6), c = X.segment<3>(9);
      const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
      Eigen::Matrix<double, 12, 1> gA;
      gA << Eigen::Vector3d::Zero(), 0.5 * n.cross(c - b), 0.5 * n.cross(a - c),
          0.5 * n.cross(b - a);
      K -= (pr.force / pr.area) * g * gA.transpose();
    }
  }
}

void SelfContact::multiply_exact(const Eigen::VectorXd& p, Eigen::VectorXd* y) const {
  for (size_t i = 0; i < pairs_.size() && i < exact_.size(); ++i) {
    const Pair& pr = pairs_[i];
    const int nodes[4] = {pr.vertex, pr.tri[0], pr.tri[1], pr.tri[2]};
    Eigen::Matrix<double, 12, 1> pe;
    for (int a = 0; a < 4; ++a) pe.segment<3>(3 * a) = p.segment<3>(3 * nodes[a]);
    const Eigen::Matrix<double, 12, 1> ye = exact_[i] * pe;
    for (int a = 0; a < 4; ++a) y->segment<3>(3 * nodes[a]) += ye.segment<3>(3 * a);
  }
  for (const SmoothSet& set : smooth_sets_) {
    if (set.nodes.empty() || set.K.rows() == 0) continue;
    const Eigen::Index n = set.K.rows();
    Eigen::VectorXd pe(n);
    for (size_t a = 0; a < set.nodes.size(); ++a)
      pe.segment<3>(3 * static_cast<Eigen::Index>(a)) = p.segment<3>(3 * set.nodes[a]);
    const Eigen::VectorXd ye = set.K * pe;
    for (size_t a = 0; a < set.nodes.size(); ++a)
      y->segment<3>(3 * set.nodes[a]) += ye.segment<3>(3 * static_cast<Eigen::Index>(a));
  }
}

void SelfContact::add_diagonal_blocks(double scale_k, double scale_c,
                                      SymmetricBlockMatrix* A) const {
  for (const Pair& pr : pairs_) {
    if (pr.stiffness == 0.0 && pr.eta == 0.0) continue;
    const Stencil st = stencil(pr);
    const Eigen::Matrix3d B = tangent_block(pr, scale_k, scale_c);
    for (int a = 0; a < 4; ++a) A->add_diagonal_block(st.nodes[a], st.c[a] * st.c[a] * B);
  }
}

double SelfContact::add(const Eigen::VectorXd& v, Eigen::VectorXd* f,
                        std::vector<Eigen::Triplet<double>>* trip, double scale_k, double scale_c) {
  const double energy = add_forces(v, f);
  for (const Pair& pr : pairs_) {
    if (pr.stiffness == 0.0 && pr.eta == 0.0) continue;
    const Stencil st = stencil(pr);
    const Eigen::Matrix3d B = tangent_block(pr, scale_k, scale_c);
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) {
        const Eigen::Matrix3d Bab = st.c[a] * st.c[b] * B;
        for (int r = 0; r < 3; ++r) {
          for (int s = 0; s < 3; ++s)
            trip->emplace_back(3 * st.nodes[a] + r, 3 * st.nodes[b] + s, Bab(r, s));
        }
      }
    }
  }
  return energy;
}

}  // namespace mvtwin::forward
