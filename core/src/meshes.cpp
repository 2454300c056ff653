// Small checks shared by the mesh structs of triangle_mesh.h and tet_mesh.h.
#include <string>

#include <Eigen/Geometry>

#include "mvtwin/core/error.h"
#include "mvtwin/core/tet_mesh.h"
#include "mvtwin/core/triangle_mesh.h"

namespace mvtwin {
namespace {

template <typename Derived>
void check_indices(const Eigen::MatrixBase<Derived>& idx, Eigen::Index n_vertices,
                   const char* what) {
  for (Eigen::Index r = 0; r < idx.rows(); ++r) {
    for (Eigen::Index c = 0; c < idx.cols(); ++c) {
      if (idx(r, c) < 0 || idx(r, c) >= n_vertices) {
        throw Error(std::string(what) + ": element " + std::to_string(r) + " refers to vertex " +
                    std::to_string(idx(r, c)) + " but there are " + std::to_string(n_vertices) +
                    " vertices");
      }
    }
  }
}

template <typename Derived>
void check_finite(const Eigen::MatrixBase<Derived>& x, const char* what, const char* field) {
  for (Eigen::Index r = 0; r < x.rows(); ++r) {
    if (!x.row(r).allFinite()) {
      throw Error(std::string(what) + ": " + field + " row " + std::to_string(r) +
                  " is not finite (NaN or Inf)");
    }
  }
}

}  // namespace

double TriangleMesh::area() const {
  double a = 0.0;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::Vector3d p0 = V.row(F(f, 0)), p1 = V.row(F(f, 1)), p2 = V.row(F(f, 2));
    a += 0.5 * (p1 - p0).cross(p2 - p0).norm();
  }
  return a;
}

void TriangleMesh::check(const char* what) const {
  check_finite(V, what, "vertex");
  check_indices(F, V.rows(), what);
}

double TetMesh::volume(int e) const {
  const Eigen::Vector3d p0 = V.row(T(e, 0)), p1 = V.row(T(e, 1)), p2 = V.row(T(e, 2)),
                        p3 = V.row(T(e, 3));
  return (p1 - p0).cross(p2 - p0).dot(p3 - p0) / 6.0;
}

void TetMesh::check(const char* what) const {
  check_finite(V, what, "vertex");
  check_indices(T, V.rows(), what);
  if (tag.size() != T.rows() || fibre.rows() != T.rows()) {
    throw Error(std::string(what) + ": " + std::to_string(T.rows()) + " tets but " +
                std::to_string(tag.size()) + " tags and " + std::to_string(fibre.rows()) +
                " fibre directions");
  }
  check_finite(fibre, what, "fibre");
  for (Eigen::Index e = 0; e < T.rows(); ++e) {
    const double vol = volume(static_cast<int>(e));
    if (!(vol > 0.0)) {
      throw Error(std::string(what) + ": tetrahedron " + std::to_string(e) +
                  (vol == 0.0 ? " is flat (zero volume)" : " is inverted (negative volume)"));
    }
  }
}

}  // namespace mvtwin
