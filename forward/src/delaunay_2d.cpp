#include "mvtwin/forward/delaunay_2d.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "mvtwin/core/error.h"

namespace mvtwin::forward {
namespace {

struct Tri {
  std::array<int, 3> v;
  Eigen::Vector2d centre;
  double radius2;
};

Tri make_tri(const std::vector<Eigen::Vector2d>& p, int a, int b, int c) {
  const Eigen::Vector2d A = p[a], B = p[b], C = p[c];
  double cross = (B - A).x() * (C - A).y() - (B - A).y() * (C - A).x();
  if (cross < 0) std::swap(b, c);
  const Eigen::Vector2d b1 = p[b] - A, c1 = p[c] - A;
  const double d = 2.0 * (b1.x() * c1.y() - b1.y() * c1.x());
  Eigen::Vector2d centre = A;
  double r2 = std::numeric_limits<double>::infinity();
  if (std::abs(d) > 0) {
    const double bb = b1.squaredNorm(), cc = c1.squaredNorm();
    const Eigen::Vector2d o((c1.y() * bb - b1.y() * cc) / d, (b1.x() * cc - c1.x() * bb) / d);
    centre = A + o;
    r2 = o.squaredNorm();
  }
  return {{a, b, c}, centre, r2};
}

}  // namespace

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
  // Super-triangle far outside every point.
  constexpr double kFar = 1e5;  // far enough that no hull triangle is lost to the super-triangle
  p.emplace_back(mid.x() - kFar * span, mid.y() - kFar * span);
  p.emplace_back(mid.x() + kFar * span, mid.y() - kFar * span);
  p.emplace_back(mid.x(), mid.y() + kFar * span);
  std::vector<Tri> tris{make_tri(p, n, n + 1, n + 2)};
  const double eps = 1e-12 * span * span;

  std::vector<Tri> keep;
  std::map<std::pair<int, int>, int> edge_count;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d& q = p[i];
    keep.clear();
    edge_count.clear();
    std::vector<std::pair<int, int>> order;  // directed boundary edges of the cavity
    for (const Tri& t : tris) {
      if ((q - t.centre).squaredNorm() < t.radius2 - eps) {
        for (int k = 0; k < 3; ++k) {
          const int a = t.v[k], b = t.v[(k + 1) % 3];
          ++edge_count[{std::min(a, b), std::max(a, b)}];
          order.emplace_back(a, b);
        }
      } else {
        keep.push_back(t);
      }
    }
    if (order.empty()) continue;  // duplicate point: skipped
    for (const auto& [a, b] : order) {
      if (edge_count[{std::min(a, b), std::max(a, b)}] == 1) keep.push_back(make_tri(p, a, b, i));
    }
    tris.swap(keep);
  }
  std::vector<std::array<int, 3>> out;
  for (const Tri& t : tris) {
    if (t.v[0] < n && t.v[1] < n && t.v[2] < n) out.push_back(t.v);
  }
  return out;
}

}  // namespace mvtwin::forward
