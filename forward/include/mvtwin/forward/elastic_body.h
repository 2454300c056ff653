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
  /// Elements within the inversion guard's range (ElasticBody::set_inversion_guard): the
  /// Gauss-Newton coefficient and the gradient of the corner tetrahedron's det F.
  struct Guard {
    int element;
    double coefficient;
    Eigen::Matrix<double, 12, 1> dJ;
  };
  std::vector<Guard> guards;
  std::vector<int> guard_of_element;  ///< index into guards or -1
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
  /// Inversion guard of the time integrator's path (gradient, tangent_times, assemble_tangent;
  /// not accumulate): a volumetric barrier on each element's corner tetrahedron,
  ///   E_g = kappa V0 phi(J),  phi(J) = -(J - j0)^2 ln(J / j0) for 0 < J < j0, else 0,
  /// with J = det F and kappa the element's mean longitudinal modulus (C11 + C22 + C33) / 3.
  /// It is C2 and zero above j0 (0.2 by default: far beyond physiological compression, so
  /// it leaves normal deformation untouched) and unbounded as J -> 0: co-rotational linear
  /// elasticity alone lets a sheared element collapse at finite energy. j0 = 0 switches it off.
  void set_inversion_guard(double j0) { guard_j0_ = j0; }
  double inversion_guard() const { return guard_j0_; }
  /// Threads of gradient() and tangent_times() (1 or 2): the elements are split in two halves
  /// whose sums are added in a fixed order, so results do not depend on it.
  void set_threads(int threads) { threads_ = threads; }

  /// First element whose corner tetrahedron is inverted or flat at x (det F <= 0), or -1.
  int first_inverted(const Eigen::VectorXd& x) const;
  /// Each element's consistent tangent at x (CorotationalTet::evaluate's, with the rotations'
  /// derivative: not symmetric) plus the inversion guard's Gauss-Newton term from rot (the
  /// gradient() at the same x): the static solve's tangent, for tangents_times(). Returns the
  /// first inverted element or -1.
  int consistent_tangents(const Eigen::VectorXd& x, const ElementRotations& rot,
                          std::vector<Eigen::MatrixXd>* K) const;
  /// y += sum over the elements of K_e p_e (all dofs) for per-element tangents K.
  void tangents_times(const std::vector<Eigen::MatrixXd>& K, const Eigen::VectorXd& p,
                      Eigen::VectorXd* y) const;
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
  int gradient_range(const std::vector<CorotationalTet<N>>& elems, int e0, int e1,
                     const Eigen::VectorXd& x, Eigen::VectorXd* g, ElementRotations* rot,
                     std::vector<ElementRotations::Guard>* guards, double* energy,
                     const Eigen::VectorXd* p, Eigen::VectorXd* Kp) const;
  template <int N>
  int consistent_order(const std::vector<CorotationalTet<N>>& elems, const Eigen::VectorXd& x,
                       const ElementRotations& rot, std::vector<Eigen::MatrixXd>* K) const;
  template <int N>
  void tangent_times_range(const std::vector<CorotationalTet<N>>& elems, int e0, int e1,
                           const ElementRotations& rot, const Eigen::VectorXd& p,
                           Eigen::VectorXd* y) const;
  template <int N>
  void tangent_times_order(const std::vector<CorotationalTet<N>>& elems,
                           const ElementRotations& rot, const Eigen::VectorXd& p,
                           Eigen::VectorXd* y) const;
  template <int N>
  void assemble_order(const std::vector<CorotationalTet<N>>& elems, const ElementRotations& rot,
                      double s, SymmetricBlockMatrix* A) const;

  SolidMesh mesh_;
  double guard_j0_ = 0.0;
  int threads_ = 1;
  std::vector<double> guard_scale_;  // kappa V0 per element
  std::vector<CorotationalTet<4>> linear_;
  std::vector<CorotationalTet<10>> quadratic_;
};

}  // namespace mvtwin::forward
