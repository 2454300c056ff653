#include "mvtwin/forward/delaunay_2d.h"

#include <cmath>
#include <set>

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

TEST(Delaunay2d, BadInput) {
  EXPECT_THROW(delaunay_2d({{0, 0}, {1, 1}}), Error);
  EXPECT_THROW(delaunay_2d({{0, 0}, {1, 1}, {NAN, 0}}), Error);
}

}  // namespace
}  // namespace mvtwin::forward
