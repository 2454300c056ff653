#include "mvtwin/core/closure_measures.h"

#include <cmath>
#include <functional>
#include <numbers>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "mvtwin/core/error.h"

namespace mvtwin {
namespace {

using Curve = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

Curve circle(double r, int n) {
  Curve c(n, 3);
  for (int i = 0; i < n; ++i) {
    const double a = -2.0 * std::numbers::pi * i / n;  // clockwise seen from +z
    c.row(i) << r * std::cos(a), r * std::sin(a), 0.0;
  }
  return c;
}

// A flat triangulated square [-12, 12]^2 at height z, keeping the triangles whose centroid
// passes `keep` (a fine mesh so that the cut edges are sharp).
TriangleMesh square(double z, const std::function<bool(double, double)>& keep) {
  const int n = 120;
  const double h = 24.0 / n;
  TriangleMesh m;
  m.V.resize((n + 1) * (n + 1), 3);
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) m.V.row(j * (n + 1) + i) << -12 + i * h, -12 + j * h, z;
  std::vector<Eigen::Vector3i> f;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
      const double cx = -12 + (i + 0.5) * h, cy = -12 + (j + 0.5) * h;
      if (!keep(cx, cy)) continue;
      f.emplace_back(a, b, c);
      f.emplace_back(a, c, d);
    }
  }
  m.F.resize(static_cast<Eigen::Index>(f.size()), 3);
  for (size_t k = 0; k < f.size(); ++k) m.F.row(static_cast<Eigen::Index>(k)) = f[k].transpose();
  return m;
}

TEST(ClosureMeasures, FullyCoveredOpeningHasNoOrifice) {
  const ClosureMeasures m =
      measure_closure(circle(10, 128), square(-3.0, [](double, double) { return true; }));
  EXPECT_NEAR(m.annulus_area_mm2,
              std::numbers::pi * 100 * std::cos(std::numbers::pi / 128) *
                  std::sin(std::numbers::pi / 128) * 128 / std::numbers::pi,
              2.0);
  EXPECT_EQ(m.orifice_area_mm2, 0.0);
  EXPECT_EQ(m.orifice_components, 0);
}

TEST(ClosureMeasures, KnownGapAndTwoOrifices) {
  // A 2 mm strip across the middle left open: area of |y| < 1 inside the circle of radius 10.
  const double strip = 2.0 * (1.0 * std::sqrt(99.0) + 100.0 * std::asin(0.1));
  const ClosureMeasures gap = measure_closure(
      circle(10, 256), square(-2.0, [](double, double y) { return std::abs(y) > 1.0; }));
  EXPECT_NEAR(gap.orifice_area_mm2, strip, 0.05 * strip);
  EXPECT_EQ(gap.orifice_components, 1);
  // A clipped gap: the middle of the strip closed, two openings remain.
  const ClosureMeasures clipped = measure_closure(
      circle(10, 256),
      square(-2.0, [](double x, double y) { return std::abs(y) > 1.0 || std::abs(x) < 2.0; }));
  EXPECT_EQ(clipped.orifice_components, 2);
  EXPECT_NEAR(clipped.orifice_area_mm2, strip - 8.0, 0.06 * strip);
  // The double orifice: each opening's area, largest first, summing to the orifice.
  ASSERT_EQ(clipped.component_areas_mm2.size(), 2u);
  EXPECT_NEAR(clipped.component_areas_mm2[0] + clipped.component_areas_mm2[1],
              clipped.orifice_area_mm2, 1e-9);
  EXPECT_NEAR(clipped.component_areas_mm2[1], 0.5 * (strip - 8.0), 0.06 * strip);
  // A clip off the middle (x in (2, 6)) leaves a large and a small opening.
  const ClosureMeasures off = measure_closure(circle(10, 256), square(-2.0, [](double x, double y) {
                                                return std::abs(y) > 1.0 || (x > 2.0 && x < 6.0);
                                              }));
  ASSERT_EQ(off.component_areas_mm2.size(), 2u);
  EXPECT_GT(off.component_areas_mm2[0], 2.0 * off.component_areas_mm2[1]);
  const double small = 2.0 * 10.0 * std::sqrt(1.0 - 0.01) - 2.0 * 6.0;  // x in (6, ~9.95), |y| < 1
  EXPECT_NEAR(off.component_areas_mm2[1], small, 0.15 * small);
}

TEST(ClosureMeasures, InvariantUnderRigidMotion) {
  const Curve a = circle(10, 256);
  const TriangleMesh l = square(-2.0, [](double, double y) { return std::abs(y) > 1.0; });
  const ClosureMeasures m0 = measure_closure(a, l);
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(30, -5, 70);
  Curve a2 = (a * R.transpose()).rowwise() + t.transpose();
  TriangleMesh l2 = l;
  l2.V = (l.V * R.transpose()).rowwise() + t.transpose();
  const ClosureMeasures m1 = measure_closure(a2, l2);
  EXPECT_NEAR(m1.orifice_area_mm2, m0.orifice_area_mm2, 0.03 * m0.orifice_area_mm2);
  EXPECT_NEAR(m1.annulus_area_mm2, m0.annulus_area_mm2, 0.01 * m0.annulus_area_mm2);
}

TEST(ClosureMeasures, BadInput) {
  const TriangleMesh l = square(0.0, [](double, double) { return true; });
  EXPECT_THROW(measure_closure(circle(10, 64), TriangleMesh{}), Error);
  EXPECT_THROW(measure_closure(circle(10, 64), l, 0.0), Error);
  Curve bad = circle(10, 64);
  bad(3, 1) = NAN;
  EXPECT_THROW(measure_closure(bad, l), Error);
}

/// A closed valve drawn by hand: each column runs flat (z = 0) from an annulus circle of radius
/// 15 mm to the closure line y = +-gap/2, then straight down for `depth` mm; the anterior half
/// (y > 0) and the posterior half (y < 0) face each other gap mm apart along the drop.
LeafletGrid hand_closed_valve(double gap, double depth) {
  const int U = 32, V = 13, K = 6;
  LeafletGrid::Points P(U * V, 3);
  for (int u = 0; u < U; ++u) {
    const double th = std::numbers::pi * u / (U / 2), x = 15.0 * std::cos(th),
                 y0 = 15.0 * std::sin(th);
    const double side = u < U / 2 ? 1.0 : -1.0;
    for (int v = 0; v < V; ++v) {
      Eigen::Vector3d q;
      if (v <= K) {
        q = {x, y0 + (side * 0.5 * gap - y0) * v / K, 0.0};
      } else {
        q = {x, side * 0.5 * gap, -depth * (v - K) / (V - 1 - K)};
      }
      P.row(v * U + u) = q.transpose();
    }
  }
  return LeafletGrid(U, V, P);
}

TEST(Coaptation, LengthOfTheApposedZone) {
  // The drop (6 mm) plus the flat part within 1 mm of the other leaflet (0.3 mm apart at the
  // closure line: the last 0.7 mm).
  const Coaptation c = measure_coaptation(hand_closed_valve(0.3, 6.0), 1.0);
  EXPECT_NEAR(c.length_mm, 6.7, 0.1);
  EXPECT_NEAR(c.max_mm, 6.7, 0.1);
  EXPECT_DOUBLE_EQ(c.coapting_fraction, 1.0);
  EXPECT_NEAR(measure_coaptation(hand_closed_valve(0.3, 3.0), 1.0).length_mm, 3.7, 0.1);
  // Leaflets 2 mm apart do not coapt.
  const Coaptation open = measure_coaptation(hand_closed_valve(2.0, 6.0), 1.0);
  EXPECT_EQ(open.length_mm, 0.0);
  EXPECT_EQ(open.coapting_fraction, 0.0);
  EXPECT_THROW(measure_coaptation(hand_closed_valve(0.3, 6.0), 0.0), Error);
}

}  // namespace
}  // namespace mvtwin
