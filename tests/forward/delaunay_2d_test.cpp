#include "mvtwin/forward/delaunay_2d.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "mvtwin/core/error.h"
#include "mvtwin/core/rng.h"

namespace mvtwin::forward {
namespace {

double orient(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
}

TEST(Delaunay2d, RandomPointsEmptyCircumcirclesAndFullHull) {
  Rng rng(5);
  std::vector<Eigen::Vector2d> p;
  for (int i = 0; i < 400; ++i) p.emplace_back(rng.uniform(0, 10), rng.uniform(0, 3));
  // Corners make the hull a known rectangle.
  p.emplace_back(0, 0);
  p.emplace_back(10, 0);
  p.emplace_back(10, 3);
  p.emplace_back(0, 3);
  const auto tris = delaunay_2d(p);
  double area = 0.0;
  for (const auto& t : tris) {
    const double o = orient(p[t[0]], p[t[1]], p[t[2]]);
    EXPECT_GT(o, 0.0) << "counter-clockwise";
    area += 0.5 * o;
    // Empty circumcircle: no point strictly inside.
    const Eigen::Vector2d a = p[t[0]], b = p[t[1]] - a, c = p[t[2]] - a;
    const double d = 2.0 * (b.x() * c.y() - b.y() * c.x());
    const Eigen::Vector2d o2((c.y() * b.squaredNorm() - b.y() * c.squaredNorm()) / d,
                             (b.x() * c.squaredNorm() - c.x() * b.squaredNorm()) / d);
    const double r2 = o2.squaredNorm();
    for (size_t i = 0; i < p.size(); ++i) {
      if (static_cast<int>(i) == t[0] || static_cast<int>(i) == t[1] || static_cast<int>(i) == t[2])
        continue;
      EXPECT_GE((p[i] - a - o2).squaredNorm(), r2 * (1 - 1e-9));
    }
  }
  EXPECT_NEAR(area, 30.0, 1e-9);
  // Euler: 2n - h - 2 triangles with h hull points (the 4 corners; random points are inside).
  EXPECT_EQ(tris.size(), 2 * p.size() - 4 - 2);
}

// The mesher's lattice: rows offset by half a column, jittered by 1e-4 (near-co-circular
// quadruples everywhere) above a row of exactly collinear points. Bowyer-Watson deciding each
// circumcircle on its own left cavities whose fans overlapped: the triangles covered 493.2 + 5.2
// of a 493.2 hull at rows 0.866 apart and 884.5 + 19.0 of 884.5 on a 30 x 30 square lattice
// (a triangle 33 mm across an unrolled leaflet on cohort seed 2026's patient 0 at 40 x 40).
// A triangulation covers its hull once: the areas add up to the hull's, every triangle is
// counter-clockwise and every interior edge has exactly one triangle on each side.
TEST(Delaunay2d, NearCoCircularLatticesCoverTheHullOnce) {
  auto jitter = [](int a, int b) {
    unsigned h = static_cast<unsigned>(a) * 73856093u ^ static_cast<unsigned>(b) * 19349663u;
    h ^= h >> 13;
    h *= 0x5bd1e995u;
    h ^= h >> 15;
    return (h % 20001) / 10000.0 - 1.0;
  };
  struct Case {
    int cols, rows;
    double row_step;
  };
  for (const Case& c :
       {Case{48, 12, 0.8660254}, Case{30, 30, 1.0}, Case{48, 12, 0.5}, Case{40, 20, 0.4}}) {
    SCOPED_TRACE(std::to_string(c.cols) + " x " + std::to_string(c.rows) + ", rows " +
                 std::to_string(c.row_step) + " apart");
    std::vector<Eigen::Vector2d> p;
    for (int u = 0; u < c.cols; ++u) p.emplace_back(u, 0.0);
    for (int u = 0; u < c.cols; ++u)
      for (int j = 1; j <= c.rows; ++j)
        p.emplace_back(u + 0.5 * (j % 2) + 1e-4 * jitter(u, j),
                       (j + 1e-4 * jitter(j, u)) * c.row_step);
    // The hull: the collinear row, the top row's extremes and the side columns.
    std::vector<Eigen::Vector2d> s = p;
    std::sort(s.begin(), s.end(), [](const auto& a, const auto& b) {
      return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
    });
    std::vector<Eigen::Vector2d> h(2 * s.size());
    int k = 0;
    for (const auto& q : s) {
      while (k >= 2 && orient(h[k - 2], h[k - 1], q) <= 0) --k;
      h[k++] = q;
    }
    for (int i = static_cast<int>(s.size()) - 2, t = k + 1; i >= 0; --i) {
      while (k >= t && orient(h[k - 2], h[k - 1], s[i]) <= 0) --k;
      h[k++] = s[i];
    }
    double hull = 0.0;
    for (int i = 0; i + 1 < k; ++i) hull += 0.5 * orient(Eigen::Vector2d::Zero(), h[i], h[i + 1]);
    const auto tris = delaunay_2d(p);
    double area = 0.0;
    std::map<std::pair<int, int>, int> directed;
    for (const auto& t : tris) {
      const double o = orient(p[t[0]], p[t[1]], p[t[2]]);
      EXPECT_GT(o, 0.0);
      area += 0.5 * o;
      for (int e = 0; e < 3; ++e) ++directed[{t[e], t[(e + 1) % 3]}];
    }
    // Slivers along the nearly straight sides may go to the super-triangle: 1e-3 of the area.
    EXPECT_NEAR(area, hull, 1e-3);
    EXPECT_LE(area, hull + 1e-9) << "triangles overlap";
    for (const auto& [e, count] : directed)
      EXPECT_EQ(count, 1) << "edge " << e.first << "-" << e.second;
  }
}

TEST(Delaunay2d, BadInput) {
  EXPECT_THROW(delaunay_2d({{0, 0}, {1, 1}}), Error);
  EXPECT_THROW(delaunay_2d({{0, 0}, {1, 1}, {NAN, 0}}), Error);
}

}  // namespace
}  // namespace mvtwin::forward
