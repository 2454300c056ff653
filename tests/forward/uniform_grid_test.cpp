// The contact searches' grid (forward/src/uniform_grid.h): a box query must return every point
// inside the box, once, whatever the points look like.
#include "uniform_grid.h"

#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <vector>

#include <gtest/gtest.h>

namespace mvtwin::forward {
namespace {

bool inside(const Eigen::Vector3d& p, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  return (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all();
}

// Every point inside the box is visited, and no point twice.
void expect_query_complete(const std::vector<Eigen::Vector3d>& points, double cell,
                           const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  const UniformGrid grid(static_cast<int>(points.size()), cell,
                         [&](int i) { return points[static_cast<size_t>(i)]; });
  std::multiset<int> seen;
  grid.for_each_near(lo, hi, [&](int i) {
    ASSERT_GE(i, 0);
    ASSERT_LT(i, static_cast<int>(points.size()));
    seen.insert(i);
  });
  for (int i = 0; i < static_cast<int>(points.size()); ++i) {
    EXPECT_LE(seen.count(i), 1u) << "point " << i << " visited twice";
    if (inside(points[static_cast<size_t>(i)], lo, hi)) {
      EXPECT_EQ(seen.count(i), 1u) << "point " << i << " inside the box was not visited";
    }
  }
}

TEST(UniformGrid, BoxQueriesReturnEveryPointInside) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> coord(-20.0, 20.0), size(0.0, 6.0);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 3000; ++i) points.emplace_back(coord(rng), coord(rng), 0.1 * coord(rng));
  int hits = 0;
  for (int q = 0; q < 200; ++q) {
    const Eigen::Vector3d lo(coord(rng), coord(rng), 0.1 * coord(rng));
    const Eigen::Vector3d hi = lo + Eigen::Vector3d(size(rng), size(rng), size(rng));
    expect_query_complete(points, 1.35, lo, hi);
    for (const auto& p : points) hits += inside(p, lo, hi);
  }
  EXPECT_GT(hits, 200);  // the boxes did hold points
}

TEST(UniformGrid, BoxesOutsideOrAroundTheWholeCloud) {
  std::vector<Eigen::Vector3d> points = {{0, 0, 0}, {1, 2, 3}, {-4, 0.5, 2}};
  expect_query_complete(points, 1.0, Eigen::Vector3d::Constant(-100),
                        Eigen::Vector3d::Constant(100));
  expect_query_complete(points, 1.0, Eigen::Vector3d::Constant(50), Eigen::Vector3d::Constant(60));
  expect_query_complete(points, 1.0, Eigen::Vector3d::Constant(-60),
                        Eigen::Vector3d::Constant(-50));
}

TEST(UniformGrid, CoincidentSingleAndNoPoints) {
  expect_query_complete(std::vector<Eigen::Vector3d>(50, Eigen::Vector3d(1, 1, 1)), 0.5,
                        Eigen::Vector3d::Constant(1), Eigen::Vector3d::Constant(1));
  expect_query_complete({Eigen::Vector3d(3, 4, 5)}, 0.5, Eigen::Vector3d::Constant(0),
                        Eigen::Vector3d::Constant(10));
  expect_query_complete({}, 0.5, Eigen::Vector3d::Constant(0), Eigen::Vector3d::Constant(10));
}

// A state blown apart (one node a kilometre away) would need ~1e18 cells of the asked size: the
// cells grow instead, and queries stay complete.
TEST(UniformGrid, FarApartPointsStayBoundedAndComplete) {
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 100; ++i) points.emplace_back(0.1 * i, 0.05 * i, 0.0);
  points.emplace_back(1e6, -1e6, 1e6);
  expect_query_complete(points, 1.0, Eigen::Vector3d(2, 1, -1), Eigen::Vector3d(5, 3, 1));
  expect_query_complete(points, 1.0, Eigen::Vector3d(1e6 - 1, -1e6 - 1, 1e6 - 1),
                        Eigen::Vector3d(1e6 + 1, -1e6 + 1, 1e6 + 1));
}

// Non-finite coordinates put every point in one cell: the query still sees each finite point.
TEST(UniformGrid, NonFiniteCoordinatesDoNotLosePoints) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<Eigen::Vector3d> points = {{0, 0, 0}, {nan, 1, 1}, {2, 2, 2}};
  expect_query_complete(points, 1.0, Eigen::Vector3d::Constant(-1), Eigen::Vector3d::Constant(3));
}

}  // namespace
}  // namespace mvtwin::forward
