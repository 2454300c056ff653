#pragma once
#include <Eigen/Core>

namespace mvtwin {

/// Element tags for regional parameters (Mansi et al. 2012, Fig. 5).
enum class LeafletTag : int { kAnterior = 1, kPosterior = 2 };

/// A tetrahedral mesh with per-element tag and fibre direction.
///   V      #V by 3 vertex positions in mm
///   T      #T by 4 vertex indices, positive orientation ((v1-v0)x(v2-v0)).(v3-v0) > 0
///   tag    #T element tags (LeafletTag values)
///   fibre  #T by 3 unit fibre directions (material axis 1)
struct TetMesh {
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> V;
  Eigen::Matrix<int, Eigen::Dynamic, 4, Eigen::RowMajor> T;
  Eigen::VectorXi tag;
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> fibre;

  /// Signed volume of element e in mm^3.
  double volume(int e) const;
  /// Throws mvtwin::Error naming `what` for bad indices, non-finite values, a size mismatch
  /// between T, tag and fibre, or an inverted or flat element.
  void check(const char* what) const;
};

}  // namespace mvtwin
