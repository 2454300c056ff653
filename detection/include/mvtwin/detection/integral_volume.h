#pragma once
// 3D integral volumes (summed-volume tables) and the Haar-like, intensity and gradient
// features the learned detectors use: any box sum in 8 lookups, whatever the box size.
#include <array>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/image_volume.h"

namespace mvtwin::detection {

/// Sums of the voxel values and of their squares over [0, i) x [0, j) x [0, k), so that the
/// sum over any axis-aligned box costs 8 lookups.
class IntegralVolume {
 public:
  explicit IntegralVolume(const ImageVolume& image);

  const std::array<int, 3>& size() const { return size_; }
  /// Sum over voxels [lo, hi) (voxel indices, half-open), clipped to the volume; 0 for an
  /// empty box.
  double sum(const Eigen::Vector3i& lo, const Eigen::Vector3i& hi) const;
  double sum_of_squares(const Eigen::Vector3i& lo, const Eigen::Vector3i& hi) const;
  /// Mean over the part of the box inside the volume (0 when none is).
  double mean(const Eigen::Vector3i& lo, const Eigen::Vector3i& hi) const;

 private:
  double lookup(const std::vector<double>& t, Eigen::Vector3i lo, Eigen::Vector3i hi) const;
  std::array<int, 3> size_;
  std::vector<double> s_, s2_;  // (nx + 1) x (ny + 1) x (nz + 1), x fastest
};

/// The features of one voxel, from boxes of half-width r voxels for each scale r in `scales`:
/// per scale the box mean, its standard deviation, three first-derivative (edge) Haar
/// features, three second-derivative (thin bright line/sheet) Haar features and a centre-
/// surround feature; then the voxel's own value. All are means (not sums), so they compare
/// across scales.
inline constexpr int kFeaturesPerScale = 9;
int feature_count(const std::vector<int>& scales);
void voxel_features(const IntegralVolume& iv, const ImageVolume& image, const Eigen::Vector3i& p,
                    const std::vector<int>& scales, float* out);

}  // namespace mvtwin::detection
