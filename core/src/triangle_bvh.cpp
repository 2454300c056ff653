#include "mvtwin/core/triangle_bvh.h"

#include <algorithm>
#include <limits>
#include <numeric>

#include "mvtwin/core/error.h"
#include "mvtwin/core/point_triangle_distance.h"

namespace mvtwin {
namespace {

constexpr int kLeafSize = 4;

double box_distance2(const Eigen::Vector3d& p, const Eigen::Vector3d& lo,
                     const Eigen::Vector3d& hi) {
  const Eigen::Vector3d d = (lo - p).cwiseMax(p - hi).cwiseMax(0.0);
  return d.squaredNorm();
}

}  // namespace

TriangleBvh::TriangleBvh(const TriangleMesh& mesh) : mesh_(mesh) {
  if (mesh_.F.rows() == 0) throw Error("closest-point search: the surface has no triangles");
  const int n = static_cast<int>(mesh_.F.rows());
  order_.resize(n);
  std::iota(order_.begin(), order_.end(), 0);
  centroids_.resize(n);
  for (int f = 0; f < n; ++f) {
    centroids_[f] =
        (mesh_.V.row(mesh_.F(f, 0)) + mesh_.V.row(mesh_.F(f, 1)) + mesh_.V.row(mesh_.F(f, 2)))
            .transpose() /
        3.0;
  }
  nodes_.reserve(2 * n / kLeafSize + 2);
  build(0, n);
}

int TriangleBvh::build(int begin, int end) {
  const int id = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (int i = begin; i < end; ++i) {
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d v = mesh_.V.row(mesh_.F(order_[i], k)).transpose();
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
  }
  nodes_[id].lo = lo;
  nodes_[id].hi = hi;
  if (end - begin <= kLeafSize) {
    nodes_[id].begin = begin;
    nodes_[id].end = end;
    return id;
  }
  int axis = 0;
  (hi - lo).maxCoeff(&axis);
  const int mid = (begin + end) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                   [&](int a, int b) { return centroids_[a][axis] < centroids_[b][axis]; });
  const int left = build(begin, mid);
  const int right = build(mid, end);
  nodes_[id].left = left;
  nodes_[id].right = right;
  return id;
}

TriangleBvh::Hit TriangleBvh::closest(const Eigen::Vector3d& p) const {
  Hit best;
  double best_d2 = std::numeric_limits<double>::infinity();
  int stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (box_distance2(p, node.lo, node.hi) >= best_d2) continue;
    if (node.left < 0) {
      for (int i = node.begin; i < node.end; ++i) {
        const int f = order_[i];
        const Eigen::Vector3d q = closest_point_on_triangle(
            p, mesh_.V.row(mesh_.F(f, 0)).transpose(), mesh_.V.row(mesh_.F(f, 1)).transpose(),
            mesh_.V.row(mesh_.F(f, 2)).transpose());
        const double d2 = (q - p).squaredNorm();
        if (d2 < best_d2) {
          best_d2 = d2;
          best.triangle = f;
          best.point = q;
        }
      }
      continue;
    }
    // Visit the nearer child first so that the far one is more often pruned.
    const Node& l = nodes_[node.left];
    const Node& r = nodes_[node.right];
    const bool left_first = box_distance2(p, l.lo, l.hi) <= box_distance2(p, r.lo, r.hi);
    stack[top++] = left_first ? node.right : node.left;
    stack[top++] = left_first ? node.left : node.right;
  }
  best.distance = std::sqrt(best_d2);
  return best;
}

}  // namespace mvtwin
