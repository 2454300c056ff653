#pragma once
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/triangle_mesh.h"

namespace mvtwin {

/// Summary of a set of distances, all in mm.
struct DistanceStats {
  int count = 0;
  double mean = 0.0;
  double sd = 0.0;   ///< population standard deviation
  double p95 = 0.0;  ///< 95th percentile (linear interpolation between order statistics)
  double max = 0.0;
};

DistanceStats distance_stats(std::vector<double> d);

/// Distance in mm from each point (rows of P, n by 3) to the closest point of the surface
/// (triangles, not vertices): the paper's point-to-mesh error (Mansi et al. 2012, Sec. 3.2.3).
std::vector<double> point_to_mesh_distances(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& P,
    const TriangleMesh& surface);

DistanceStats point_to_mesh_distance(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& P,
    const TriangleMesh& surface);

/// Both directions between two surfaces (vertices of one to triangles of the other) and the
/// pooled symmetric statistics, so that a surface that covers only part of the other is seen.
struct SymmetricDistance {
  DistanceStats a_to_b;
  DistanceStats b_to_a;
  DistanceStats symmetric;  ///< over the union of both sets of distances
};

SymmetricDistance symmetric_surface_distance(const TriangleMesh& a, const TriangleMesh& b);

}  // namespace mvtwin
