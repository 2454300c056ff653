#include "mvtwin/core/annulus_plane.h"

#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "mvtwin/core/error.h"

namespace mvtwin {

using Curve = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

Eigen::Vector3d atrial_direction(const Eigen::Ref<const Curve>& annulus) {
  const Eigen::Index n = annulus.rows();
  const Eigen::Vector3d c = annulus.colwise().mean().transpose();
  Eigen::Vector3d area = Eigen::Vector3d::Zero();
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d a = annulus.row(i).transpose() - c;
    const Eigen::Vector3d b = annulus.row((i + 1) % n).transpose() - c;
    area += 0.5 * a.cross(b);
  }
  if (!(area.norm() > 0.0)) throw Error("annulus curve is degenerate (zero enclosed area)");
  return -area.normalized();
}

AnnulusPlane least_squares_plane(const Eigen::Ref<const Curve>& annulus) {
  AnnulusPlane plane;
  plane.point = annulus.colwise().mean().transpose();
  const Curve centred = annulus.rowwise() - plane.point.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(centred.transpose() * centred);
  plane.normal = eig.eigenvectors().col(0);  // smallest eigenvalue
  if (plane.normal.dot(atrial_direction(annulus)) < 0.0) plane.normal = -plane.normal;
  plane.from_landmarks = false;
  return plane;
}

AnnulusPlane annulus_plane(const ValveFrame& frame) {
  if (frame.observed(Landmark::kAnterolateralTrigone) &&
      frame.observed(Landmark::kPosteromedialTrigone) &&
      frame.observed(Landmark::kPosteriorAnnulusMidpoint)) {
    const Eigen::Vector3d t1 = frame.landmark(Landmark::kAnterolateralTrigone);
    const Eigen::Vector3d t2 = frame.landmark(Landmark::kPosteromedialTrigone);
    const Eigen::Vector3d pm = frame.landmark(Landmark::kPosteriorAnnulusMidpoint);
    const Eigen::Vector3d n = (t2 - t1).cross(pm - t1);
    if (n.norm() > 1e-9 * (t2 - t1).squaredNorm()) {
      AnnulusPlane plane;
      plane.point = (t1 + t2 + pm) / 3.0;
      plane.normal = n.normalized();
      if (plane.normal.dot(atrial_direction(frame.annulus)) < 0.0) plane.normal = -plane.normal;
      plane.from_landmarks = true;
      return plane;
    }
  }
  return least_squares_plane(frame.annulus);
}

TipToAnnulusPlane tip_to_annulus_plane(const ValveFrame& frame) {
  const AnnulusPlane plane = annulus_plane(frame);
  auto tip = [&](Landmark l, double s) -> double {
    if (frame.observed(l)) return plane.signed_distance(frame.landmark(l));
    if (frame.la_surface) return plane.signed_distance(frame.la_surface->sample(s, 1.0));
    return std::numeric_limits<double>::quiet_NaN();
  };
  TipToAnnulusPlane out;
  out.anterior_mm = tip(Landmark::kAnteriorLeafletTip, 0.25);
  out.posterior_mm = tip(Landmark::kPosteriorLeafletTip, 0.75);
  out.plane_from_landmarks = plane.from_landmarks;
  return out;
}

}  // namespace mvtwin
