#pragma once
#include <array>
#include <vector>

#include <Eigen/Core>

namespace mvtwin {

/// A scalar 3D image in physical space. Voxel (i, j, k) sits at
///   origin + direction * diag(spacing) * (i, j, k)^T   (mm),
/// and is stored at data[i + nx * (j + ny * k)] (x fastest, as in NIfTI and ITK).
struct ImageVolume {
  std::array<int, 3> size{0, 0, 0};
  Eigen::Vector3d spacing = Eigen::Vector3d::Ones();  ///< mm
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();   ///< mm
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();
  std::vector<float> data;
  /// Time of the frame in s (3D+t sequences), 0 for a single volume.
  double time_s = 0.0;

  std::size_t num_voxels() const { return static_cast<std::size_t>(size[0]) * size[1] * size[2]; }
  float at(int i, int j, int k) const {
    return data[static_cast<std::size_t>(i) +
                static_cast<std::size_t>(size[0]) * (j + static_cast<std::size_t>(size[1]) * k)];
  }
  /// Physical position of voxel (i, j, k) in mm.
  Eigen::Vector3d position(double i, double j, double k) const {
    return origin + direction * spacing.cwiseProduct(Eigen::Vector3d(i, j, k));
  }
};

}  // namespace mvtwin
