#pragma once
#include <Eigen/Core>

namespace mvtwin::forward {

/// A co-rotational tetrahedron with N = 4 (linear) or N = 10 (quadratic, VTK node order:
/// corners 0-3, then mid-edges 01, 12, 02, 03, 13, 23) nodes and a linear anisotropic material.
///
/// Energy  E(x) = 1/2 u^T K0 u,  u = R^T x - X  (node-wise),  where R is the rotation of the
/// polar decomposition F = R S of the deformation gradient of the corner tetrahedron and K0 the
/// small-strain stiffness at rest. The elastic force is -g with g = R K0 u. For an anisotropic
/// material g is not exactly dE/dx and its exact derivative is not symmetric, so both the
/// consistent tangent dg/dx (including the derivative of R) and the symmetric "warped" tangent
/// R K0 R^T are provided.
template <int N>
class CorotationalTet {
  static_assert(N == 4 || N == 10, "linear (4) or quadratic (10) tetrahedra");

 public:
  static constexpr int kDofs = 3 * N;
  using Nodes = Eigen::Matrix<double, N, 3>;
  using Vector = Eigen::Matrix<double, kDofs, 1>;
  using Matrix = Eigen::Matrix<double, kDofs, kDofs>;
  using Stiffness6 = Eigen::Matrix<double, 6, 6>;
  using StrainMatrix = Eigen::Matrix<double, 6, kDofs>;

  CorotationalTet() = default;
  /// Rest positions (mid-edge nodes at or near the edge midpoints: isoparametric) and the 6x6
  /// global stiffness C in MPa (Voigt, engineering shear). Precondition: positive rest volume.
  CorotationalTet(const Nodes& rest, const Stiffness6& C);

  double rest_volume() const { return volume_; }
  const Matrix& rest_stiffness() const { return K0_; }
  /// Lumped mass fractions (sum 1): V/4 per corner for N = 4; HRZ lumping for N = 10.
  static Eigen::Matrix<double, N, 1> mass_fractions();

  /// Evaluates at current positions x. Returns false (and leaves outputs untouched) when the
  /// corner tetrahedron is inverted or flat (det F <= 0). Any output may be null.
  ///   g           3N gradient (minus the elastic force), N
  ///   consistent  3N x 3N dg/dx including the rotation derivative
  ///   warped      3N x 3N R K0 R^T (symmetric positive semi-definite)
  ///   energy      1/2 u^T K0 u, N mm
  bool evaluate(const Nodes& x, Vector* g, Matrix* consistent, Matrix* warped,
                double* energy = nullptr) const;

  /// The pieces of evaluate() for the warped tangent, so that a time step computes each
  /// element's rotation once and reuses it for the gradient, products with the tangent and
  /// (when a factorization is due) its assembly.
  ///   rotation        R of the corner tetrahedron at x; false when inverted or flat
  ///   gradient        g = R K0 (R^T x - X), the energy if asked, and, with p, also R K0 R^T p
  ///                   (one pass over K0 for both)
  ///   tangent_times   R K0 R^T p
  ///   warped_tangent  R K0 R^T
  bool rotation(const Nodes& x, Eigen::Matrix3d* R) const;
  /// det F of the corner tetrahedron at x and its gradient with respect to the four corners
  /// (12 entries, corner-major).
  double corner_jacobian(const Nodes& x, Eigen::Matrix<double, 12, 1>* gradient) const;
  void gradient(const Eigen::Matrix3d& R, const Nodes& x, Vector* g, double* energy,
                const Vector* p = nullptr, Vector* Kp = nullptr) const;
  Vector tangent_times(const Eigen::Matrix3d& R, const Vector& p) const;
  void warped_tangent(const Eigen::Matrix3d& R, Matrix* K) const;

  /// Green-Lagrange-free small strain of the co-rotated displacement at the centroid, Voigt.
  Eigen::Matrix<double, 6, 1> centroid_strain(const Nodes& x) const;

  /// Strain-displacement matrix at barycentric point L (rest configuration; isoparametric for
  /// N = 10, so mid-edge nodes may sit off the edges' midpoints), and det dX/dxi there.
  StrainMatrix strain_matrix(const Eigen::Vector4d& L, double* det_jacobian = nullptr) const;
  /// Smallest det dX/dxi at the quadrature points (> 0 for a valid element; 6 x the volume for
  /// a straight-sided one).
  double min_jacobian() const { return min_jacobian_; }
  /// The same for rest positions X without building the element.
  static double min_jacobian_of(const Nodes& X);

 private:
  Nodes X_;
  Eigen::Matrix3d Dm_inv_;
  Matrix K0_;
  double volume_ = 0.0;
  double min_jacobian_ = 0.0;
};

/// Polar decomposition F = R S with R a proper rotation; false when det F <= 0.
bool polar_decomposition(const Eigen::Matrix3d& F, Eigen::Matrix3d* R, Eigen::Matrix3d* S);

extern template class CorotationalTet<4>;
extern template class CorotationalTet<10>;

}  // namespace mvtwin::forward
