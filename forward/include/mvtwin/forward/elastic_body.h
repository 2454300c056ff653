#pragma once
#include <functional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "mvtwin/forward/corotational_tet.h"
#include "mvtwin/forward/solid_mesh.h"
#include "mvtwin/forward/transversely_isotropic.h"

namespace mvtwin::forward {

/// Which derivative of the elastic forces to assemble.
enum class Tangent {
  kWarped,      ///< R K0 R^T: symmetric, the paper's (SOFA's) co-rotational stiffness
  kConsistent,  ///< exact derivative including the rotation: non-symmetric for anisotropy
};

/// The elastic leaflet tissue of a solid mesh: per-element co-rotational tetrahedra with the
/// material of their tag and their fibre. Positions are flattened: x[3 i + k].
class ElasticBody {
 public:
  /// material(tag) gives each element's material; throws mvtwin::Error for an invalid
  /// material or an inverted/flat rest element.
  ElasticBody(SolidMesh mesh, const std::function<TransverselyIsotropic(int tag)>& material);

  const SolidMesh& mesh() const { return mesh_; }
  int num_dofs() const { return 3 * mesh_.num_nodes(); }
  Eigen::VectorXd rest_positions() const;

  /// Lumped nodal masses (t) for density rho (t/mm^3).
  Eigen::VectorXd lumped_mass(double density) const;

  /// Adds the energy gradient (minus the elastic force) to *g and, when H is not null, the
  /// tangent's triplets to *H. Returns the index of the first inverted element, or -1.
  int accumulate(const Eigen::VectorXd& x, Eigen::VectorXd* g,
                 std::vector<Eigen::Triplet<double>>* H, Tangent tangent,
                 double* energy = nullptr) const;

 private:
  template <int N>
  int accumulate_order(const std::vector<CorotationalTet<N>>& elems, const Eigen::VectorXd& x,
                       Eigen::VectorXd* g, std::vector<Eigen::Triplet<double>>* H, Tangent tangent,
                       double* energy) const;

  SolidMesh mesh_;
  std::vector<CorotationalTet<4>> linear_;
  std::vector<CorotationalTet<10>> quadratic_;
};

}  // namespace mvtwin::forward
