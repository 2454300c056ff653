#pragma once
#include <array>
#include <vector>

#include <Eigen/Core>

namespace mvtwin::forward {

/// Delaunay triangulation of points in the plane (Bowyer-Watson), counter-clockwise triangles
/// of point indices. Points should be distinct; exactly co-circular sets (lattices) get one of
/// their valid triangulations. Throws mvtwin::Error for fewer than 3 points or non-finite
/// coordinates.
std::vector<std::array<int, 3>> delaunay_2d(const std::vector<Eigen::Vector2d>& points);

}  // namespace mvtwin::forward
