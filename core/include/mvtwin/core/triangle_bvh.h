#pragma once
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/triangle_mesh.h"

namespace mvtwin {

/// Axis-aligned bounding-box hierarchy over the triangles of a surface, for closest-point
/// queries. The surface is copied; build is O(n log n), a query about O(log n).
class TriangleBvh {
 public:
  struct Hit {
    double distance = 0.0;  ///< mm
    int triangle = -1;      ///< index into F
    Eigen::Vector3d point;  ///< closest point on the surface, mm
  };

  explicit TriangleBvh(const TriangleMesh& mesh);

  /// Closest point of the surface to p. The surface must have at least one triangle.
  Hit closest(const Eigen::Vector3d& p) const;

 private:
  struct Node {
    Eigen::Vector3d lo, hi;
    int left = -1, right = -1;  // children, or -1 for a leaf
    int begin = 0, end = 0;     // range into order_ for a leaf
  };
  int build(int begin, int end);

  TriangleMesh mesh_;
  std::vector<int> order_;
  std::vector<Node> nodes_;
  std::vector<Eigen::Vector3d> centroids_;
};

}  // namespace mvtwin
