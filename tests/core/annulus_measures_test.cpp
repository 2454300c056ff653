#include "mvtwin/core/annulus_measures.h"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "mvtwin/core/annulus_plane.h"

namespace mvtwin {
namespace {

using std::numbers::pi;

// An elliptic saddle annulus on the grid convention: u = 0 at +y (anterolateral commissure),
// running clockwise seen from +z (the atrium) through +x (anterior). Semi-axes a (x), b (y);
// saddle z = h/2 cos(2 theta) (highs anterior/posterior, lows at the commissures).
ValveFrame ellipse_frame(double a, double b, double h, int ures,
                         const Eigen::Isometry3d& pose = Eigen::Isometry3d::Identity()) {
  ValveFrame f;
  f.annulus.resize(ures, 3);
  for (int u = 0; u < ures; ++u) {
    const double theta = pi / 2 - 2 * pi * u / ures;
    f.annulus.row(u) = (pose * Eigen::Vector3d(a * std::cos(theta), b * std::sin(theta),
                                               0.5 * h * std::cos(2 * theta)))
                           .transpose();
  }
  for (auto& l : f.landmarks) l.setConstant(std::nan(""));
  return f;
}

double ramanujan_perimeter(double a, double b) {
  return pi * (3 * (a + b) - std::sqrt((3 * a + b) * (a + 3 * b)));
}

TEST(AnnulusMeasures, FlatEllipse) {
  const double a = 14.0, b = 18.0;
  const AnnulusMeasures m = annulus_measures(ellipse_frame(a, b, 0.0, 64));
  EXPECT_NEAR(m.perimeter_mm, ramanujan_perimeter(a, b), 0.05);
  EXPECT_NEAR(m.area_3d_mm2, pi * a * b, 0.5);
  EXPECT_NEAR(m.area_projected_mm2, pi * a * b, 0.5);
  EXPECT_NEAR(m.height_mm, 0.0, 1e-9);
  EXPECT_NEAR(m.commissural_width_mm, 2 * b, 1e-9);
  EXPECT_NEAR(m.alpm_diameter_mm, 2 * b, 1e-3);
  EXPECT_NEAR(m.ap_diameter_mm, 2 * a, 1e-3);
  EXPECT_NEAR(m.anterior_arc_mm, 0.5 * ramanujan_perimeter(a, b), 0.05);
  EXPECT_TRUE(std::isnan(m.intertrigonal_mm));
}

TEST(AnnulusMeasures, SaddleHeightAndRigidInvariance) {
  const double h = 6.0;
  const ValveFrame f = ellipse_frame(14, 18, h, 48);
  const AnnulusMeasures m = annulus_measures(f);
  EXPECT_NEAR(m.height_mm, h, 0.02);
  EXPECT_GT(m.area_3d_mm2, m.area_projected_mm2);  // the saddle adds out-of-plane area
  // Same annulus moved rigidly: every measure unchanged.
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.rotate(Eigen::AngleAxisd(1.1, Eigen::Vector3d(1, 2, 3).normalized()));
  pose.pretranslate(Eigen::Vector3d(30, -12, 70));
  const AnnulusMeasures r = annulus_measures(ellipse_frame(14, 18, h, 48, pose));
  EXPECT_NEAR(r.perimeter_mm, m.perimeter_mm, 1e-9);
  EXPECT_NEAR(r.area_3d_mm2, m.area_3d_mm2, 1e-9);
  EXPECT_NEAR(r.height_mm, m.height_mm, 1e-9);
  EXPECT_NEAR(r.ap_diameter_mm, m.ap_diameter_mm, 1e-9);
  EXPECT_NEAR(r.alpm_diameter_mm, m.alpm_diameter_mm, 1e-9);
}

TEST(AnnulusPlane, AtrialDirectionFollowsTheGridConvention) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.rotate(Eigen::AngleAxisd(2.0, Eigen::Vector3d(0, 1, 1).normalized()));
  const ValveFrame f = ellipse_frame(14, 18, 5.0, 32, pose);
  EXPECT_NEAR(atrial_direction(f.annulus).dot(pose.linear() * Eigen::Vector3d::UnitZ()), 1.0, 1e-9);
}

TEST(AnnulusPlane, TipDistancesFromLandmarks) {
  ValveFrame f = ellipse_frame(14, 18, 6.0, 32);
  // Trigones and posterior mid-point on a plane tilted about the y axis by 10 degrees.
  const double tilt = 10.0 * pi / 180;
  auto on_plane = [&](double x, double y) { return Eigen::Vector3d(x, y, std::tan(tilt) * x); };
  f.landmarks[index(Landmark::kAnterolateralTrigone)] = on_plane(10, 10);
  f.landmarks[index(Landmark::kPosteromedialTrigone)] = on_plane(10, -10);
  f.landmarks[index(Landmark::kPosteriorAnnulusMidpoint)] = on_plane(-14, 0);
  f.landmarks[index(Landmark::kAnteriorLeafletTip)] =
      on_plane(2, 0) + Eigen::Vector3d(0, 0, -5 / std::cos(tilt));
  f.landmarks[index(Landmark::kPosteriorLeafletTip)] =
      on_plane(-3, 1) + Eigen::Vector3d(0, 0, 2 / std::cos(tilt));
  for (Landmark l : {Landmark::kAnterolateralTrigone, Landmark::kPosteromedialTrigone,
                     Landmark::kPosteriorAnnulusMidpoint, Landmark::kAnteriorLeafletTip,
                     Landmark::kPosteriorLeafletTip}) {
    f.landmark_observed[index(l)] = true;
  }
  const TipToAnnulusPlane t = tip_to_annulus_plane(f);
  EXPECT_TRUE(t.plane_from_landmarks);
  EXPECT_NEAR(t.anterior_mm, -5.0, 1e-9);  // 5 mm into the ventricle
  EXPECT_NEAR(t.posterior_mm, 2.0, 1e-9);  // 2 mm into the atrium
  // Without trigones the least-squares plane (z = 0 for a symmetric saddle) is used.
  f.landmark_observed[index(Landmark::kAnterolateralTrigone)] = false;
  const TipToAnnulusPlane u = tip_to_annulus_plane(f);
  EXPECT_FALSE(u.plane_from_landmarks);
  EXPECT_NEAR(u.anterior_mm, f.landmarks[index(Landmark::kAnteriorLeafletTip)].z(), 1e-9);
}

}  // namespace
}  // namespace mvtwin
