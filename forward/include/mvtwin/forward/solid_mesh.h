#pragma once
#include <array>
#include <map>
#include <utility>

#include <Eigen/Core>

#include "mvtwin/core/tet_mesh.h"

namespace mvtwin::forward {

/// Order of the tetrahedra of a solid.
enum class TetOrder : int { kLinear = 4, kQuadratic = 10 };

/// A tetrahedral solid of linear (4-node) or quadratic (10-node, VTK order) elements.
///   V      #nodes by 3 rest positions, mm; the first `corner_nodes` are the linear mesh's
///          vertices, the rest (quadratic only) mid-edge nodes
///   T      #elements by 10 node indices (only the first 4 used for linear)
///   tag, fibre  per element, as in core TetMesh
struct SolidMesh {
  TetOrder order = TetOrder::kLinear;
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> V;
  Eigen::Matrix<int, Eigen::Dynamic, 10, Eigen::RowMajor> T;
  Eigen::VectorXi tag;
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> fibre;
  int corner_nodes = 0;
  /// For quadratic meshes: the node at the middle of each edge (a < b) of the linear mesh.
  std::map<std::pair<int, int>, int> mid_edge;

  int nodes_per_element() const { return static_cast<int>(order); }
  int num_elements() const { return static_cast<int>(T.rows()); }
  int num_nodes() const { return static_cast<int>(V.rows()); }
  /// Node in the middle of corner nodes a and b (quadratic meshes only; -1 if none).
  int mid_node(int a, int b) const;
};

/// The linear mesh as a solid, optionally promoted to quadratic tetrahedra (mid-edge nodes at
/// edge midpoints, shared between neighbours).
SolidMesh make_solid(const TetMesh& mesh, TetOrder order);

/// A box [0,lx] x [0,ly] x [0,lz] of nx*ny*nz hexahedra, each split into 6 tetrahedra around
/// its main diagonal (a conforming Kuhn subdivision), all positively oriented. Tag 1, fibre x.
TetMesh box_tet_mesh(const Eigen::Vector3d& size, const std::array<int, 3>& cells);

}  // namespace mvtwin::forward
