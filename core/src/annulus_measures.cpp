#include <Eigen/Geometry>

#include "mvtwin/core/annulus_measures.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "mvtwin/core/annulus_plane.h"

namespace mvtwin {

using Curve = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

AnnulusMeasures annulus_measures(const ValveFrame& frame) {
  const int ures = static_cast<int>(frame.annulus.rows());
  constexpr int kRefine = 16;  // spline points per grid interval
  const int n = ures * kRefine;
  const Curve c = resample_closed_curve(frame.annulus, n);
  const AnnulusPlane plane = least_squares_plane(frame.annulus);
  const Eigen::Vector3d centroid = c.colwise().mean().transpose();

  AnnulusMeasures m;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  Eigen::Vector3d vector_area = Eigen::Vector3d::Zero();
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d a = c.row(i).transpose(), b = c.row((i + 1) % n).transpose();
    const double seg = (b - a).norm();
    m.perimeter_mm += seg;
    (i < n / 2 ? m.anterior_arc_mm : m.posterior_arc_mm) += seg;
    m.area_3d_mm2 += 0.5 * (a - centroid).cross(b - centroid).norm();
    vector_area += 0.5 * (a - centroid).cross(b - centroid);
    const double h = plane.signed_distance(a);
    lo = std::min(lo, h);
    hi = std::max(hi, h);
  }
  m.area_projected_mm2 = std::abs(vector_area.dot(plane.normal));
  m.height_mm = hi - lo;

  // In-plane frame: e1 along the commissural line (anterolateral -> posteromedial), e2 towards
  // the anterior annulus.
  auto project = [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    return p - plane.normal * plane.signed_distance(p);
  };
  const Eigen::Vector3d c_al = c.row(0).transpose(), c_pm = c.row(n / 2).transpose();
  m.commissural_width_mm = (c_pm - c_al).norm();
  Eigen::Vector3d e1 = project(c_pm) - project(c_al);
  e1 = (e1 - plane.normal * plane.normal.dot(e1)).normalized();
  Eigen::Vector3d e2 = plane.normal.cross(e1);
  const Eigen::Vector3d ant_mid = c.row(n / 4).transpose();
  if (e2.dot(ant_mid - centroid) < 0.0) e2 = -e2;

  double e1_lo = std::numeric_limits<double>::infinity(), e1_hi = -e1_lo;
  for (int i = 0; i < n; ++i) {
    const double x = e1.dot(c.row(i).transpose() - centroid);
    e1_lo = std::min(e1_lo, x);
    e1_hi = std::max(e1_hi, x);
  }
  m.alpm_diameter_mm = e1_hi - e1_lo;

  // AP: from the posterior mid-point along e2 to where that line crosses the anterior arc.
  const Eigen::Vector3d post_mid = c.row(3 * n / 4).transpose();
  const double x0 = e1.dot(post_mid - centroid);
  m.ap_diameter_mm = std::numeric_limits<double>::quiet_NaN();
  for (int i = 0; i < n / 2; ++i) {
    const Eigen::Vector3d a = c.row(i).transpose(), b = c.row(i + 1).transpose();
    const double xa = e1.dot(a - centroid) - x0, xb = e1.dot(b - centroid) - x0;
    if ((xa <= 0.0 && xb > 0.0) || (xa >= 0.0 && xb < 0.0)) {
      const Eigen::Vector3d q = a + (xa / (xa - xb)) * (b - a);
      m.ap_diameter_mm = (project(q) - project(post_mid)).norm();
      break;
    }
  }

  m.intertrigonal_mm = frame.observed(Landmark::kAnterolateralTrigone) &&
                               frame.observed(Landmark::kPosteromedialTrigone)
                           ? (frame.landmark(Landmark::kAnterolateralTrigone) -
                              frame.landmark(Landmark::kPosteromedialTrigone))
                                 .norm()
                           : std::numeric_limits<double>::quiet_NaN();
  return m;
}

}  // namespace mvtwin
