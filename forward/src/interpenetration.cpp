#include "mvtwin/forward/interpenetration.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <set>
#include <utility>

#include <Eigen/LU>

namespace mvtwin::forward {
namespace {

// Sub-tetrahedra of a VTK quadratic tetrahedron (corners 0-3, mid-edges 01, 12, 02, 03, 13, 23).
constexpr int kSub[8][4] = {{0, 4, 6, 7}, {4, 1, 5, 8}, {6, 5, 2, 9}, {7, 8, 9, 3},
                            {6, 8, 4, 5}, {6, 8, 5, 9}, {6, 8, 9, 7}, {6, 8, 7, 4}};

std::int64_t cell_key(std::int64_t i, std::int64_t j, std::int64_t k) {
  return ((i & 0x1fffff) << 42) | ((j & 0x1fffff) << 21) | (k & 0x1fffff);
}

}  // namespace

Interpenetration find_interpenetration(const ValveModel& m, const Eigen::VectorXd& x,
                                       double margin) {
  const SolidMesh& mesh = m.mesh;
  const bool quadratic = mesh.order == TetOrder::kQuadratic;
  auto X = [&](int node) { return Eigen::Vector3d(x.segment<3>(3 * node)); };
  // Linear sub-tetrahedra with their leaflet tag, binned by bounding box.
  struct Sub {
    int node[4];
    int tag;
  };
  std::vector<Sub> subs;
  for (int e = 0; e < mesh.num_elements(); ++e) {
    if (quadratic) {
      for (const auto& s : kSub)
        subs.push_back(
            {{mesh.T(e, s[0]), mesh.T(e, s[1]), mesh.T(e, s[2]), mesh.T(e, s[3])}, mesh.tag[e]});
    } else {
      subs.push_back({{mesh.T(e, 0), mesh.T(e, 1), mesh.T(e, 2), mesh.T(e, 3)}, mesh.tag[e]});
    }
  }
  const double h = 2.0;  // mm, about an element
  auto cell = [&](double v) { return static_cast<std::int64_t>(std::floor(v / h)); };
  std::vector<std::pair<std::int64_t, int>> binned;
  for (size_t k = 0; k < subs.size(); ++k) {
    Eigen::Vector3d lo = X(subs[k].node[0]), hi = lo;
    for (int j = 1; j < 4; ++j) {
      lo = lo.cwiseMin(X(subs[k].node[j]));
      hi = hi.cwiseMax(X(subs[k].node[j]));
    }
    if (!lo.allFinite() || !hi.allFinite()) continue;
    for (std::int64_t I = cell(lo.x()); I <= cell(hi.x()); ++I)
      for (std::int64_t J = cell(lo.y()); J <= cell(hi.y()); ++J)
        for (std::int64_t K = cell(lo.z()); K <= cell(hi.z()); ++K)
          binned.emplace_back(cell_key(I, J, K), static_cast<int>(k));
  }
  std::sort(binned.begin(), binned.end());

  // Surface nodes (corners of both surfaces and, for quadratic meshes, their mid-edge nodes)
  // with the tag of the leaflet they belong to.
  std::set<int> surface;
  const int L = m.options.layers;
  for (Eigen::Index f = 0; f < m.surface_triangles.rows(); ++f) {
    for (int layer : {0, L}) {
      int nd[3];
      for (int k = 0; k < 3; ++k) nd[k] = m.node(m.surface_triangles(f, k), layer);
      for (int k = 0; k < 3; ++k) {
        surface.insert(nd[k]);
        if (quadratic) {
          const int mid = mesh.mid_node(nd[k], nd[(k + 1) % 3]);
          if (mid >= 0) surface.insert(mid);
        }
      }
    }
  }
  std::vector<int> node_tag(mesh.num_nodes(), -1);
  for (int e = 0; e < mesh.num_elements(); ++e) {
    for (int a = 0; a < mesh.nodes_per_element(); ++a) {
      // A node shared by both leaflets (the commissural seam) belongs to neither: skip it.
      int& t = node_tag[mesh.T(e, a)];
      t = t == -1 || t == mesh.tag[e] ? mesh.tag[e] : -2;
    }
  }
  Interpenetration out;
  for (int node : surface) {
    if (node_tag[node] < 0) continue;
    const Eigen::Vector3d q = X(node);
    if (!q.allFinite()) continue;
    ++out.checked;
    const std::int64_t key = cell_key(cell(q.x()), cell(q.y()), cell(q.z()));
    auto it = std::lower_bound(binned.begin(), binned.end(), std::make_pair(key, -1));
    bool inside = false;
    for (; it != binned.end() && it->first == key && !inside; ++it) {
      const Sub& s = subs[it->second];
      if (s.tag == node_tag[node]) continue;
      const Eigen::Vector3d a = X(s.node[0]);
      Eigen::Matrix3d M;
      M << X(s.node[1]) - a, X(s.node[2]) - a, X(s.node[3]) - a;
      const Eigen::FullPivLU<Eigen::Matrix3d> lu(M);
      if (!lu.isInvertible()) continue;
      const Eigen::Vector3d w = lu.solve(q - a);
      inside = w.minCoeff() > margin && w.sum() < 1.0 - margin;
    }
    if (inside) out.nodes.push_back(node);
  }
  return out;
}

}  // namespace mvtwin::forward
