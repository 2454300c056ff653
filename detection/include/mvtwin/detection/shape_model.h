#pragma once
// A statistical shape model of the LA leaflet surface on the (u, v) grid, placed by the
// landmarks: what keeps a detected surface valve-like (Mansi et al. 2012, Sec. 2.1).
#include <array>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/landmark.h"
#include "mvtwin/core/valve_sequence.h"

namespace mvtwin::detection {

using Points3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// The landmarks that place the surface: trigones, posterior annulus mid-point, commissures and
/// leaflet tips (the papillary tips move independently of the leaflets).
inline constexpr std::array<Landmark, 7> kPlacingLandmarks = {
    Landmark::kAnterolateralTrigone,     Landmark::kPosteromedialTrigone,
    Landmark::kPosteriorAnnulusMidpoint, Landmark::kAnterolateralCommissure,
    Landmark::kPosteromedialCommissure,  Landmark::kAnteriorLeafletTip,
    Landmark::kPosteriorLeafletTip};

/// x -> scale * R * x + t.
struct Similarity {
  double scale = 1;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Eigen::Vector3d apply(const Eigen::Vector3d& x) const { return scale * R * x + t; }
  Similarity inverse() const;
};

/// Least-squares similarity taking `from` onto `to` (rows are corresponding points; Umeyama).
Similarity fit_similarity(const Points3& from, const Points3& to);

/// A frame's placing landmarks (7 by 3); throws mvtwin::Error when one is not observed.
Points3 placing_landmarks(const ValveFrame& frame);

/// Point distribution model: mean and principal modes of surfaces mapped into the model frame
/// (each training surface by the similarity that takes its landmarks onto the mean landmarks).
class ShapeModel {
 public:
  ShapeModel() = default;
  /// Trains from frames that have an LA surface and observed placing landmarks, on the grid of
  /// the first (others are resampled). Keeps the modes that explain `variance_kept` of the
  /// variance. Throws mvtwin::Error with fewer than 3 usable frames.
  static ShapeModel train(const std::vector<const ValveFrame*>& frames,
                          double variance_kept = 0.98);

  int ures() const { return ures_; }
  int vres() const { return vres_; }
  int modes() const { return static_cast<int>(sd_.size()); }
  const Points3& mean_landmarks() const { return mean_landmarks_; }
  const Eigen::VectorXd& mean() const { return mean_; }
  const Eigen::MatrixXd& basis() const { return basis_; }
  const Eigen::VectorXd& sd() const { return sd_; }

  /// The mean surface placed by landmarks (image space): the mean-shape baseline.
  Points3 place_mean(const Points3& landmarks) const;
  /// The closest model surface to `points` (image space, ures*vres by 3, grid order), with the
  /// mode coefficients limited to +-`limit_sd` standard deviations, using the placement
  /// `to_image` (model frame -> image).
  Points3 constrain(const Points3& points, const Similarity& to_image, double limit_sd = 3.0,
                    int max_modes = -1) const;
  /// Model frame -> image for a set of landmarks.
  Similarity placement(const Points3& landmarks) const;

  /// Flat storage for model files: ures, vres, then the arrays.
  std::vector<double> serialize() const;
  static ShapeModel deserialize(const std::vector<double>& data);

 private:
  int ures_ = 0, vres_ = 0;
  Points3 mean_landmarks_;
  Eigen::VectorXd mean_;   // 3 * ures * vres
  Eigen::MatrixXd basis_;  // 3 * ures * vres by modes, orthonormal columns
  Eigen::VectorXd sd_;     // per mode
};

}  // namespace mvtwin::detection
