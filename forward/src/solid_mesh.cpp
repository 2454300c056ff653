#include "mvtwin/forward/solid_mesh.h"

#include <Eigen/Geometry>
#include <Eigen/LU>

#include "mvtwin/core/error.h"

namespace mvtwin::forward {

int SolidMesh::mid_node(int a, int b) const {
  const auto it = mid_edge.find({std::min(a, b), std::max(a, b)});
  return it == mid_edge.end() ? -1 : it->second;
}

SolidMesh make_solid(const TetMesh& mesh, TetOrder order) {
  mesh.check("solid mesh");
  SolidMesh s;
  s.order = order;
  s.tag = mesh.tag;
  s.fibre = mesh.fibre;
  s.corner_nodes = static_cast<int>(mesh.V.rows());
  s.T.setConstant(mesh.T.rows(), 10, -1);
  s.T.leftCols<4>() = mesh.T;
  std::vector<Eigen::RowVector3d> extra;
  if (order == TetOrder::kQuadratic) {
    constexpr int kEdge[6][2] = {{0, 1}, {1, 2}, {0, 2}, {0, 3}, {1, 3}, {2, 3}};
    for (Eigen::Index e = 0; e < mesh.T.rows(); ++e) {
      for (int k = 0; k < 6; ++k) {
        const int a = mesh.T(e, kEdge[k][0]), b = mesh.T(e, kEdge[k][1]);
        const auto key = std::make_pair(std::min(a, b), std::max(a, b));
        auto it = s.mid_edge.find(key);
        if (it == s.mid_edge.end()) {
          it = s.mid_edge.emplace(key, s.corner_nodes + static_cast<int>(extra.size())).first;
          extra.push_back(0.5 * (mesh.V.row(a) + mesh.V.row(b)));
        }
        s.T(e, 4 + k) = it->second;
      }
    }
  }
  s.V.resize(s.corner_nodes + static_cast<Eigen::Index>(extra.size()), 3);
  s.V.topRows(s.corner_nodes) = mesh.V;
  for (size_t i = 0; i < extra.size(); ++i)
    s.V.row(s.corner_nodes + static_cast<Eigen::Index>(i)) = extra[i];
  return s;
}

TetMesh box_tet_mesh(const Eigen::Vector3d& size, const std::array<int, 3>& n) {
  if (n[0] < 1 || n[1] < 1 || n[2] < 1 || !(size.array() > 0).all()) {
    throw Error("box mesh: sizes and cell counts must be positive");
  }
  TetMesh m;
  const int nx = n[0] + 1, ny = n[1] + 1, nz = n[2] + 1;
  auto id = [&](int i, int j, int k) { return i + nx * (j + ny * k); };
  m.V.resize(nx * ny * nz, 3);
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        m.V.row(id(i, j, k)) << size.x() * i / n[0], size.y() * j / n[1], size.z() * k / n[2];
      }
    }
  }
  // Kuhn: the 6 monotone paths from corner 000 to 111 of each cube.
  const int paths[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  std::vector<Eigen::Vector4i> tets;
  for (int k = 0; k < n[2]; ++k) {
    for (int j = 0; j < n[1]; ++j) {
      for (int i = 0; i < n[0]; ++i) {
        for (const auto& p : paths) {
          int c[3] = {i, j, k};
          Eigen::Vector4i t;
          t[0] = id(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            ++c[p[s]];
            t[s + 1] = id(c[0], c[1], c[2]);
          }
          const Eigen::Vector3d p0 = m.V.row(t[0]), p1 = m.V.row(t[1]), p2 = m.V.row(t[2]),
                                p3 = m.V.row(t[3]);
          if ((p1 - p0).cross(p2 - p0).dot(p3 - p0) < 0) std::swap(t[1], t[2]);
          tets.push_back(t);
        }
      }
    }
  }
  m.T.resize(static_cast<Eigen::Index>(tets.size()), 4);
  for (size_t e = 0; e < tets.size(); ++e)
    m.T.row(static_cast<Eigen::Index>(e)) = tets[e].transpose();
  m.tag.setOnes(m.T.rows());
  m.fibre.resize(m.T.rows(), 3);
  m.fibre.rowwise() = Eigen::RowVector3d(1, 0, 0);
  return m;
}

}  // namespace mvtwin::forward
