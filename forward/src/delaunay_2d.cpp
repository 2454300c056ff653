#include "mvtwin/forward/delaunay_2d.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <utility>

#include "mvtwin/core/error.h"

namespace mvtwin::forward {
namespace {

using Real = long double;

// Twice the signed area of (a, b, c): positive when counter-clockwise.
Real orient(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  const Real bx = Real(b.x()) - a.x(), by = Real(b.y()) - a.y();
  const Real cx = Real(c.x()) - a.x(), cy = Real(c.y()) - a.y();
  return bx * cy - by * cx;
}

// Positive when q lies inside the circumcircle of the counter-clockwise (a, b, c). Relative to
// q, in extended precision: the terms stay of the triangle's size, not of its distance from the
// origin.
Real incircle(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
              const Eigen::Vector2d& q) {
  const Real ax = Real(a.x()) - q.x(), ay = Real(a.y()) - q.y();
  const Real bx = Real(b.x()) - q.x(), by = Real(b.y()) - q.y();
  const Real cx = Real(c.x()) - q.x(), cy = Real(c.y()) - q.y();
  const Real a2 = ax * ax + ay * ay, b2 = bx * bx + by * by, c2 = cx * cx + cy * cy;
  return ax * (by * c2 - b2 * cy) - ay * (bx * c2 - b2 * cx) + a2 * (bx * cy - by * cx);
}

std::uint64_t key(int a, int b) {
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) |
         static_cast<std::uint32_t>(b);
}

}  // namespace

// Bowyer-Watson with a cavity that is a valid star around the new point whatever the rounding:
// the cavity grows from the triangle that holds the point through neighbours whose
// circumcircle holds it, and a triangle whose outer edge the point does not see is taken out
// again. The circumcircle test alone (each triangle decided on its own) left cavities with
// holes or hidden edges on near-co-circular lattices, and their fans overlapped (a triangle
// 33 mm across an unrolled leaflet, measured on cohort seed 2026's patient 0 at 40 x 40).
std::vector<std::array<int, 3>> delaunay_2d(const std::vector<Eigen::Vector2d>& in) {
  const int n = static_cast<int>(in.size());
  if (n < 3) throw Error("delaunay_2d: needs at least 3 points");
  Eigen::Vector2d lo = in[0], hi = in[0];
  for (const auto& q : in) {
    if (!q.allFinite()) throw Error("delaunay_2d: non-finite point");
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  const double span = std::max((hi - lo).maxCoeff(), 1e-12);
  const Eigen::Vector2d mid = 0.5 * (lo + hi);
  std::vector<Eigen::Vector2d> p = in;
  // Super-triangle far outside every point (counter-clockwise).
  constexpr double kFar = 1e5;  // far enough that no hull triangle is lost to the super-triangle
  p.emplace_back(mid.x() - kFar * span, mid.y() - kFar * span);
  p.emplace_back(mid.x() + kFar * span, mid.y() - kFar * span);
  p.emplace_back(mid.x(), mid.y() + kFar * span);
  // Triangles by stable index (a removed one is marked dead; compacted when most are dead),
  // each directed edge -> its triangle.
  std::vector<std::array<int, 3>> tris{{n, n + 1, n + 2}};
  std::vector<char> dead{0};
  int live = 1;
  const double dup2 = 1e-24 * span * span;
  std::unordered_map<std::uint64_t, int> edge_of;
  auto index_edges = [&] {
    edge_of.clear();
    for (int t = 0; t < static_cast<int>(tris.size()); ++t)
      for (int k = 0; k < 3; ++k) edge_of[key(tris[t][k], tris[t][(k + 1) % 3])] = t;
  };
  auto neighbour = [&](int a, int b) {  // the triangle across the directed edge (a, b)
    const auto it = edge_of.find(key(b, a));
    return it == edge_of.end() ? -1 : it->second;
  };
  auto holds = [&](int t, const Eigen::Vector2d& q) {
    const auto& v = tris[t];
    return orient(p[v[0]], p[v[1]], q) >= 0 && orient(p[v[1]], p[v[2]], q) >= 0 &&
           orient(p[v[2]], p[v[0]], q) >= 0;
  };
  index_edges();
  std::unordered_map<int, char> state;  // per triangle: 2 forced into the cavity, -1 kept out
  std::vector<int> stack, cavity;
  int last = 0;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d& q = p[i];
    // The triangle that holds q (on its boundary included): a walk from the last new triangle,
    // a scan should the walk not end.
    int seed = -1;
    {
      int t = last;
      for (int steps = 0; steps < 4 * live + 16 && seed < 0; ++steps) {
        int next = -1;
        for (int k = 0; k < 3 && next < 0; ++k) {
          const int a = tris[t][k], b = tris[t][(k + 1) % 3];
          if (orient(p[a], p[b], q) < 0) next = neighbour(a, b);
        }
        if (next < 0) {
          if (holds(t, q)) seed = t;
          break;
        }
        t = next;
      }
      for (int u = 0; u < static_cast<int>(tris.size()) && seed < 0; ++u)
        if (!dead[u] && holds(u, q)) seed = u;
    }
    if (seed < 0) continue;  // cannot happen inside the super-triangle; skipped rather than broken
    {
      bool duplicate = false;
      for (int k = 0; k < 3; ++k) duplicate |= (p[tris[seed][k]] - q).squaredNorm() <= dup2;
      if (duplicate) continue;  // duplicate point: skipped
    }
    // Grow from the seed through neighbours whose circumcircle holds q; then drop any triangle
    // with an outer edge that q does not see strictly (or, for the seed and what it forced, add
    // the neighbour across such an edge: q lies on it), and grow again.
    std::unordered_map<int, char> circle;  // incircle decided once per triangle
    auto in_circle = [&](int t) {
      auto [it, fresh] = circle.try_emplace(t, 0);
      if (fresh) it->second = incircle(p[tris[t][0]], p[tris[t][1]], p[tris[t][2]], q) > 0;
      return it->second != 0;
    };
    state.clear();
    state[seed] = 2;
    std::unordered_map<int, char> member;
    for (int round = 0;; ++round) {
      if (round > live + 3) throw Error("delaunay_2d: no valid cavity (internal error)");
      member.clear();
      member[seed] = 1;
      stack.assign(1, seed);
      cavity.clear();
      while (!stack.empty()) {
        const int t = stack.back();
        stack.pop_back();
        cavity.push_back(t);
        for (int k = 0; k < 3; ++k) {
          const int u = neighbour(tris[t][k], tris[t][(k + 1) % 3]);
          if (u < 0 || member.count(u)) continue;
          const auto st = state.find(u);
          const char s_u = st == state.end() ? 0 : st->second;
          if (s_u == -1 || (s_u != 2 && !in_circle(u))) continue;
          member[u] = 1;
          stack.push_back(u);
        }
      }
      bool changed = false;
      for (int t : cavity) {
        for (int k = 0; k < 3; ++k) {
          const int a = tris[t][k], b = tris[t][(k + 1) % 3];
          const int u = neighbour(a, b);
          if ((u >= 0 && member.count(u)) || orient(p[a], p[b], q) > 0) continue;
          if (state[t] == 2) {
            if (u >= 0 && state[u] != 2) {
              state[u] = 2;
              changed = true;
            }
          } else if (state[t] != -1) {
            state[t] = -1;
            changed = true;
          }
        }
      }
      if (!changed) break;
    }
    // Replace the cavity by the fan of its outer edges around q.
    std::vector<std::array<int, 3>> fan;
    for (int t : cavity) {
      for (int k = 0; k < 3; ++k) {
        const int a = tris[t][k], b = tris[t][(k + 1) % 3];
        const int u = neighbour(a, b);
        if (u < 0 || !member.count(u)) fan.push_back({a, b, i});
      }
    }
    for (int t : cavity) {
      for (int k = 0; k < 3; ++k) edge_of.erase(key(tris[t][k], tris[t][(k + 1) % 3]));
      dead[t] = 1;
      --live;
    }
    for (const auto& f : fan) {
      const int t = static_cast<int>(tris.size());
      tris.push_back(f);
      dead.push_back(0);
      ++live;
      for (int k = 0; k < 3; ++k) edge_of[key(f[k], f[(k + 1) % 3])] = t;
      last = t;
    }
    if (static_cast<int>(tris.size()) > 2 * live + 64) {  // compact
      std::vector<std::array<int, 3>> kept;
      kept.reserve(live);
      for (size_t t = 0; t < tris.size(); ++t)
        if (!dead[t]) kept.push_back(tris[t]);
      tris.swap(kept);
      dead.assign(tris.size(), 0);
      last = static_cast<int>(tris.size()) - 1;
      index_edges();
    }
  }
  std::vector<std::array<int, 3>> out;
  for (size_t t = 0; t < tris.size(); ++t) {
    if (!dead[t] && tris[t][0] < n && tris[t][1] < n && tris[t][2] < n) out.push_back(tris[t]);
  }
  return out;
}

}  // namespace mvtwin::forward
