#include "mvtwin/core/leaflet_grid.h"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "mvtwin/core/error.h"
#include "mvtwin/core/valve_sequence.h"

namespace mvtwin {
namespace {

using std::numbers::pi;

// An analytic smooth "skirt": a cone segment hanging from a circle of radius R.
Eigen::Vector3d skirt(double s, double t) {
  const double a = -2 * pi * s;  // clockwise seen from +z
  const double r = 15.0 - 8.0 * t;
  return {r * std::cos(a), r * std::sin(a), -12.0 * t + 2.0 * std::cos(2 * a)};
}

LeafletGrid make_grid(int ures, int vres) {
  LeafletGrid::Points P(ures * vres, 3);
  for (int v = 0; v < vres; ++v) {
    for (int u = 0; u < ures; ++u)
      P.row(v * ures + u) = skirt(double(u) / ures, double(v) / (vres - 1)).transpose();
  }
  return LeafletGrid(ures, vres, P);
}

TEST(LeafletGrid, RejectsBadResolution) {
  EXPECT_THROW(LeafletGrid(7, 10, LeafletGrid::Points(70, 3)), Error);
  EXPECT_THROW(LeafletGrid(10, 2, LeafletGrid::Points(20, 3)), Error);
  EXPECT_THROW(LeafletGrid(10, 10, LeafletGrid::Points(99, 3)), Error);
}

TEST(LeafletGrid, ResamplingKeepsCorrespondence) {
  const LeafletGrid g = make_grid(30, 30);
  // Refining by an integer factor reproduces every old grid point exactly.
  const LeafletGrid fine = g.resampled(60, 59);
  for (int v = 0; v < 30; ++v) {
    for (int u = 0; u < 30; ++u) {
      EXPECT_LT((fine.at(2 * u, 2 * v) - g.at(u, v)).norm(), 1e-9) << u << "," << v;
    }
  }
  // A new grid point (u', v') lies on the analytic surface at (u'/ures', v'/(vres'-1)).
  const LeafletGrid other = g.resampled(40, 20);
  double worst = 0;
  for (int v = 0; v < 20; ++v) {
    for (int u = 0; u < 40; ++u) {
      worst = std::max(worst, (other.at(u, v) - skirt(u / 40.0, v / 19.0)).norm());
    }
  }
  EXPECT_LT(worst, 0.05);  // cubic interpolation of a smooth surface, 3 mm spacing
  // Round trip back to the original grid.
  const LeafletGrid back = fine.resampled(30, 30);
  EXPECT_LT((back.points() - g.points()).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(LeafletGrid, TriangulationIsClosedAroundAndOrientedToVentricle) {
  const LeafletGrid g = make_grid(16, 5);
  const TriangleMesh m = g.triangulate();
  EXPECT_EQ(m.F.rows(), 2 * 16 * 4);
  // Area converges to the analytic surface area as the grid refines.
  const double a1 = make_grid(32, 16).triangulate().area();
  const double a2 = make_grid(128, 64).triangulate().area();
  const double a3 = make_grid(256, 128).triangulate().area();
  EXPECT_LT(std::abs(a3 - a2), std::abs(a2 - a1));
  // Normals point down (into the ventricle) on average for a skirt hanging in -z.
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (int f = 0; f < m.F.rows(); ++f) {
    const Eigen::Vector3d p0 = m.V.row(m.F(f, 0)), p1 = m.V.row(m.F(f, 1)), p2 = m.V.row(m.F(f, 2));
    n += (p1 - p0).cross(p2 - p0);
  }
  EXPECT_LT(n.z(), 0.0);
  // Leaflet tags: first half of u anterior.
  EXPECT_EQ(g.column_tag(0), LeafletTag::kAnterior);
  EXPECT_EQ(g.column_tag(7), LeafletTag::kAnterior);
  EXPECT_EQ(g.column_tag(8), LeafletTag::kPosterior);
  EXPECT_EQ(g.column_tag(16), LeafletTag::kAnterior);  // wraps
}

TEST(LeafletGrid, RadialLength) {
  // Column length of the cone: sqrt(8^2 + 12^2) plus the saddle term, which is constant in t.
  const LeafletGrid g = make_grid(64, 40);
  EXPECT_NEAR(g.radial_length(0), std::hypot(8.0, 12.0), 1e-9);
  EXPECT_NEAR(g.radial_length_at(0.0), std::hypot(8.0, 12.0), 1e-6);
}

TEST(ValveSequence, ResampleClosedCurve) {
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> c(12, 3);
  for (int i = 0; i < 12; ++i) c.row(i) = skirt(i / 12.0, 0.0).transpose();
  const auto fine = resample_closed_curve(c, 48);
  for (int i = 0; i < 12; ++i) EXPECT_LT((fine.row(4 * i) - c.row(i)).norm(), 1e-12);
  for (int i = 0; i < 48; ++i)
    EXPECT_LT((fine.row(i).transpose() - skirt(i / 48.0, 0.0)).norm(), 0.1);
}

}  // namespace
}  // namespace mvtwin
