#include "mvtwin/core/point_to_mesh_distance.h"

#include <cmath>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "mvtwin/core/point_triangle_distance.h"
#include "mvtwin/core/rng.h"
#include "mvtwin/core/triangle_bvh.h"

namespace mvtwin {
namespace {

using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

// A flat n x n grid of squares of side h in the plane z = 0, from (0,0) to (n h, n h).
TriangleMesh plane_mesh(int n, double h, double z = 0.0) {
  TriangleMesh m;
  m.V.resize((n + 1) * (n + 1), 3);
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) m.V.row(j * (n + 1) + i) << i * h, j * h, z;
  }
  m.F.resize(2 * n * n, 3);
  int f = 0;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
      m.F.row(f++) << a, b, c;
      m.F.row(f++) << a, c, d;
    }
  }
  return m;
}

TEST(PointTriangleDistance, EveryRegion) {
  const Eigen::Vector3d a(0, 0, 0), b(2, 0, 0), c(0, 2, 0);
  // face, edges, vertices
  EXPECT_TRUE(
      closest_point_on_triangle({0.5, 0.5, 3}, a, b, c).isApprox(Eigen::Vector3d(0.5, 0.5, 0)));
  EXPECT_TRUE(closest_point_on_triangle({1, -1, 0}, a, b, c).isApprox(Eigen::Vector3d(1, 0, 0)));
  EXPECT_TRUE(closest_point_on_triangle({-1, 1, 1}, a, b, c).isApprox(Eigen::Vector3d(0, 1, 0)));
  EXPECT_TRUE(closest_point_on_triangle({2, 2, 0}, a, b, c).isApprox(Eigen::Vector3d(1, 1, 0)));
  EXPECT_TRUE(closest_point_on_triangle({-1, -1, 5}, a, b, c).isApprox(a));
  EXPECT_TRUE(closest_point_on_triangle({5, -1, 0}, a, b, c).isApprox(b));
  EXPECT_TRUE(closest_point_on_triangle({-1, 5, 0}, a, b, c).isApprox(c));
}

TEST(PointTriangleDistance, DegenerateTriangles) {
  const Eigen::Vector3d p(1, 1, 0);
  // collinear
  const Eigen::Vector3d q = closest_point_on_triangle(p, {0, 0, 0}, {1, 0, 0}, {2, 0, 0});
  EXPECT_NEAR((q - p).norm(), 1.0, 1e-12);
  // all three vertices equal
  const Eigen::Vector3d r = closest_point_on_triangle(p, {3, 1, 0}, {3, 1, 0}, {3, 1, 0});
  EXPECT_NEAR((r - p).norm(), 2.0, 1e-12);
}

TEST(TriangleBvh, MatchesBruteForce) {
  Rng rng(42);
  TriangleMesh m;
  const int nf = 500;
  m.V.resize(3 * nf, 3);
  m.F.resize(nf, 3);
  for (int f = 0; f < nf; ++f) {
    const Eigen::Vector3d c(rng.uniform(-20, 20), rng.uniform(-20, 20), rng.uniform(-20, 20));
    for (int k = 0; k < 3; ++k) {
      m.V.row(3 * f + k) =
          (c + Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal())).transpose();
      m.F(f, k) = 3 * f + k;
    }
  }
  const TriangleBvh bvh(m);
  for (int i = 0; i < 300; ++i) {
    const Eigen::Vector3d p(rng.uniform(-30, 30), rng.uniform(-30, 30), rng.uniform(-30, 30));
    double best = 1e300;
    for (int f = 0; f < nf; ++f) {
      best = std::min(best, (closest_point_on_triangle(p, m.V.row(m.F(f, 0)).transpose(),
                                                       m.V.row(m.F(f, 1)).transpose(),
                                                       m.V.row(m.F(f, 2)).transpose()) -
                             p)
                                .norm());
    }
    const TriangleBvh::Hit h = bvh.closest(p);
    EXPECT_NEAR(h.distance, best, 1e-12);
    EXPECT_NEAR((h.point - p).norm(), h.distance, 1e-12);
  }
}

TEST(PointToMeshDistance, AnalyticPlane) {
  const TriangleMesh m = plane_mesh(10, 1.0);
  Points P(4, 3);
  P << 5.3, 4.1, 2.0,   // above the face: distance 2
      5.0, 5.0, -0.5,   // below a vertex: 0.5
      -3.0, 5.0, 4.0,   // beyond the x=0 edge: hypot(3, 4) = 5
      13.0, 14.0, 0.0;  // beyond the corner (10,10): 5
  const std::vector<double> d = point_to_mesh_distances(P, m);
  EXPECT_NEAR(d[0], 2.0, 1e-12);
  EXPECT_NEAR(d[1], 0.5, 1e-12);
  EXPECT_NEAR(d[2], 5.0, 1e-12);
  EXPECT_NEAR(d[3], 5.0, 1e-12);
  // Triangles, not vertices: a point over a face centre is not at the vertex distance.
  EXPECT_NEAR(point_to_mesh_distances(Points{{0.5, 0.25, 0.1}}, m)[0], 0.1, 1e-12);
}

TEST(PointToMeshDistance, Statistics) {
  const DistanceStats s =
      distance_stats({1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21});
  EXPECT_EQ(s.count, 21);
  EXPECT_DOUBLE_EQ(s.mean, 11.0);
  EXPECT_NEAR(s.sd, std::sqrt(440.0 / 12.0), 1e-12);  // population SD of 1..21
  EXPECT_DOUBLE_EQ(s.p95, 20.0);                      // 0.95 * 20 = 19 -> the 20th value
  EXPECT_DOUBLE_EQ(s.max, 21.0);
  EXPECT_EQ(distance_stats({}).count, 0);
}

TEST(PointToMeshDistance, SymmetricSeesPartialCoverage) {
  // A small plane 1 mm above a large one: small->large is 1 everywhere, large->small is not.
  const TriangleMesh big = plane_mesh(20, 1.0);
  const TriangleMesh small = plane_mesh(5, 1.0, 1.0);
  const SymmetricDistance s = symmetric_surface_distance(small, big);
  EXPECT_NEAR(s.a_to_b.mean, 1.0, 1e-12);
  EXPECT_NEAR(s.a_to_b.max, 1.0, 1e-12);
  EXPECT_GT(s.b_to_a.max, 15.0);
  EXPECT_GT(s.symmetric.mean, s.a_to_b.mean);
  EXPECT_EQ(s.symmetric.count, s.a_to_b.count + s.b_to_a.count);
}

}  // namespace
}  // namespace mvtwin
