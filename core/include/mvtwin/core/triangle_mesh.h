#pragma once
#include <Eigen/Core>

namespace mvtwin {

/// A triangle surface.
///   V  #V by 3 vertex positions in mm
///   F  #F by 3 vertex indices, counter-clockwise seen from the side the normal points to
struct TriangleMesh {
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> V;
  Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor> F;

  /// Total area in mm^2.
  double area() const;
  /// Throws mvtwin::Error naming `what` if an index is out of range or a coordinate is not
  /// finite.
  void check(const char* what) const;
};

}  // namespace mvtwin
