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
  EXPECT_NEAR(m.annulus_area_mm2, std::numbers::pi * 100 * std::cos(std::numbers::pi / 128) *
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
      circle(10, 256), square(-2.0, [](double x, double y) {
        return std::abs(y) > 1.0 || std::abs(x) < 2.0;
      }));
  EXPECT_EQ(clipped.orifice_components, 2);
  EXPECT_NEAR(clipped.orifice_area_mm2, strip - 8.0, 0.06 * strip);
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

}  // namespace
}  // namespace mvtwin
