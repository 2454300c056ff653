#pragma once
#include <Eigen/Core>

namespace mvtwin {

/// Closest point to p on the triangle (a, b, c), exact for every region (vertices, edges,
/// face) and for degenerate triangles (Ericson, Real-Time Collision Detection, Sec. 5.1.5).
Eigen::Vector3d closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                          const Eigen::Vector3d& b, const Eigen::Vector3d& c);

}  // namespace mvtwin
