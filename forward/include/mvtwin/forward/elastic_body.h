#pragma once
#include <functional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "mvtwin/forward/corotational_tet.h"
#include "mvtwin/forward/solid_mesh.h"
#include "mvtwin/forward/symmetric_block_matrix.h"
#include "mvtwin/forward/transversely_isotropic.h"

namespace mvtwin::forward {

/// Which derivative of the elastic forces to assemble.
enum class Tangent {
  kWarped,      ///< R K0 R^T: symmetric, the paper's (SOFA's) co-rotational stiffness
  kConsistent,  ///< exact derivative including the rotation: non-symmetric for anisotropy
};

/// Co-rotational frames of every element at some positions: computed with the gradient and
/// reused, at the same positions, by products with the tangent and by its assembly.
struct ElementRotations {
  std::vector<Eigen::Matrix3d> R;
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

  /// The time integrator's path (warped tangent). Sets *g (all dofs) to the energy gradient at
  /// x and stores the element rotations in *rot; with p, also sets *Kp = K p (the tangent at
  /// x) in the same pass. Returns the first inverted element or -1.
  int gradient(const Eigen::VectorXd& x, Eigen::VectorXd* g, ElementRotations* rot,
               double* energy = nullptr, const Eigen::VectorXd* p = nullptr,
               Eigen::VectorXd* Kp = nullptr) const;
  /// y += K p with K the warped tangent at the rotations' positions (all dofs).
  void tangent_times(const ElementRotations& rot, const Eigen::VectorXd& p,
                     Eigen::VectorXd* y) const;
  /// Adds s x K into A, whose clique e is element e (the mesh's node lists in order).
  void assemble_tangent(const ElementRotations& rot, double s, SymmetricBlockMatrix* A) const;
  /// Node lists of the elements, the first cliques of a SymmetricBlockMatrix.
  std::vector<std::vector<int>> element_cliques() const;

 private:
  template <int N>
  int accumulate_order(const std::vector<CorotationalTet<N>>& elems, const Eigen::VectorXd& x,
                       Eigen::VectorXd* g, std::vector<Eigen::Triplet<double>>* H, Tangent tangent,
                       double* energy) const;

  template <int N>
  int gradient_order(const std::vector<CorotationalTet<N>>& elems, const Eigen::VectorXd& x,
                     Eigen::VectorXd* g, ElementRotations* rot, double* energy,
                     const Eigen::VectorXd* p, Eigen::VectorXd* Kp) const;
  template <int N>
  void tangent_times_order(const std::vector<CorotationalTet<N>>& elems,
                           const ElementRotations& rot, const Eigen::VectorXd& p,
                           Eigen::VectorXd* y) const;
  template <int N>
  void assemble_order(const std::vector<CorotationalTet<N>>& elems, const ElementRotations& rot,
                      double s, SymmetricBlockMatrix* A) const;

  SolidMesh mesh_;
  std::vector<CorotationalTet<4>> linear_;
  std::vector<CorotationalTet<10>> quadratic_;
};

}  // namespace mvtwin::forward
