#include <Eigen/Geometry>

#include "mvtwin/core/point_to_mesh_distance.h"

#include <algorithm>
#include <cmath>

#include "mvtwin/core/triangle_bvh.h"

namespace mvtwin {

using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

DistanceStats distance_stats(std::vector<double> d) {
  DistanceStats s;
  s.count = static_cast<int>(d.size());
  if (d.empty()) return s;
  double sum = 0.0;
  for (double x : d) sum += x;
  s.mean = sum / d.size();
  double ss = 0.0;
  for (double x : d) ss += (x - s.mean) * (x - s.mean);
  s.sd = std::sqrt(ss / d.size());
  std::sort(d.begin(), d.end());
  s.max = d.back();
  const double pos = 0.95 * (d.size() - 1);
  const auto i = static_cast<size_t>(std::floor(pos));
  const double f = pos - i;
  s.p95 = i + 1 < d.size() ? (1 - f) * d[i] + f * d[i + 1] : d[i];
  return s;
}

std::vector<double> point_to_mesh_distances(const Eigen::Ref<const Points>& P,
                                            const TriangleMesh& surface) {
  const TriangleBvh bvh(surface);
  std::vector<double> d(P.rows());
  for (Eigen::Index i = 0; i < P.rows(); ++i) d[i] = bvh.closest(P.row(i).transpose()).distance;
  return d;
}

DistanceStats point_to_mesh_distance(const Eigen::Ref<const Points>& P,
                                     const TriangleMesh& surface) {
  return distance_stats(point_to_mesh_distances(P, surface));
}

SymmetricDistance symmetric_surface_distance(const TriangleMesh& a, const TriangleMesh& b) {
  std::vector<double> ab = point_to_mesh_distances(a.V, b);
  std::vector<double> ba = point_to_mesh_distances(b.V, a);
  SymmetricDistance s;
  s.a_to_b = distance_stats(ab);
  s.b_to_a = distance_stats(ba);
  ab.insert(ab.end(), ba.begin(), ba.end());
  s.symmetric = distance_stats(std::move(ab));
  return s;
}

}  // namespace mvtwin
