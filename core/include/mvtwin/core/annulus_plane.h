#pragma once
#include <Eigen/Core>

#include "mvtwin/core/valve_sequence.h"

namespace mvtwin {

/// A plane with a unit normal that points into the left atrium.
struct AnnulusPlane {
  Eigen::Vector3d point;
  Eigen::Vector3d normal;
  /// True when built from the two trigones and the posterior annulus mid-point (the paper's
  /// definition, Sec. 3.2); false when those were not observed and the least-squares plane of
  /// the annulus curve was used instead.
  bool from_landmarks = false;

  /// Signed distance in mm, positive on the atrial side.
  double signed_distance(const Eigen::Vector3d& p) const { return normal.dot(p - point); }
};

/// Unit normal of the annulus curve pointing into the atrium, from the grid convention (u runs
/// clockwise seen from the atrium): minus the direction of the curve's vector area.
Eigen::Vector3d atrial_direction(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& annulus);

/// The annulus plane of a frame (see AnnulusPlane::from_landmarks).
AnnulusPlane annulus_plane(const ValveFrame& frame);

/// Least-squares plane of a closed curve, normal towards the atrium.
AnnulusPlane least_squares_plane(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& annulus);

/// Signed distances in mm from the leaflet tips to the annulus plane, positive into the atrium
/// (paper Fig. 14). Tips come from the landmarks when observed, else from the surface grid
/// (anterior tip at u = ures/4, posterior at u = 3*ures/4, on the free edge); NaN when neither
/// is available.
struct TipToAnnulusPlane {
  double anterior_mm = 0.0;
  double posterior_mm = 0.0;
  bool plane_from_landmarks = false;
};
TipToAnnulusPlane tip_to_annulus_plane(const ValveFrame& frame);

}  // namespace mvtwin
