#pragma once
#include <vector>

#include <Eigen/SparseCore>

struct cholmod_factor_struct;

namespace mvtwin::forward {

/// The structure of a supernodal Cholesky factor L L^T = P A P^T (CHOLMOD's supernodal symbolic
/// analysis: supernode k holds columns super[k] .. super[k+1]-1, its row indices are
/// s[pi[k]] .. s[pi[k+1]-1] (its own columns first, then the rows below, ascending) and its
/// values a column-major block at px[k]), and a split of its elimination tree in two: each
/// supernode is in group 0, group 1 (whole subtrees of about equal work) or the top (-1, the
/// separators above them). Work below a group's subtrees never touches the other group, so
/// the two groups can be factorized or substituted at once, the top after (forward) or before
/// (backward) them.
struct SupernodalStructure {
  int n = 0;
  std::vector<int> super, pi, px, s, perm;
  std::vector<int> parent;        ///< per supernode, -1 for a root
  std::vector<int> group_of;      ///< per supernode: 0, 1, or -1 (the top)
  std::vector<int> super_of;      ///< per column
  std::vector<int> column_group;  ///< per column: its supernode's group
  /// The supernodes of group 0, group 1 and the top (parts[2]), each ascending (children
  /// before parents), and the top's columns.
  std::vector<int> parts[3], top_columns;
  size_t xsize = 0;

  int num_supernodes() const { return static_cast<int>(super.size()) - 1; }
  /// From a CHOLMOD supernodal factor, symbolic or numeric (int indices). False otherwise.
  bool set(const cholmod_factor_struct* L);
};

/// Numeric supernodal Cholesky factorization (left-looking, as CHOLMOD's, with LAPACK/BLAS on
/// each supernode's block) on a SupernodalStructure, the two groups at once when threads > 1.
/// Every supernode receives its descendants' updates in an order fixed by the structure alone
/// (a top supernode: group 0's, then group 1's, then the top's), so the factor is the same bit
/// for bit on one thread or two. Scalar is double (dgemm, dpotrf, dtrsm) or float (sgemm,
/// spotrf, strsm: the single-precision preconditioner factorized in single precision, half the
/// memory traffic and twice the SIMD width of double's; docs/forward-status.md).
template <typename Scalar>
class SupernodalNumeric {
 public:
  /// Prepares for matrices with A's pattern (the lower triangle, column major, that the
  /// structure was analysed for). False if an entry of A falls outside the structure or the
  /// process has no BLAS/LAPACK for Scalar.
  bool prepare(const SupernodalStructure& structure, const Eigen::SparseMatrix<double>& A);
  /// Factorizes A (the prepared pattern). False if A is not positive definite (in Scalar's
  /// precision).
  bool factorize(const Eigen::SparseMatrix<double>& A, int threads);
  /// The factor's values, laid out as the structure says.
  const std::vector<Scalar>& values() const { return x_; }

 private:
  bool factorize_supernode(int j, int source_group, std::vector<int>* map);

  const SupernodalStructure* st_ = nullptr;
  std::vector<size_t> dest_;  // per entry of A: its place in x_
  std::vector<Scalar> x_;
  // Left-looking: the supernodes whose next rows to update fall in supernode j, by the group
  // that finished them (0, 1, top = 2): pending_[g][j].
  std::vector<std::vector<int>> pending_[3];
  std::vector<int> next_;  // per supernode: position of its next row to send updates to
};

extern template class SupernodalNumeric<double>;
extern template class SupernodalNumeric<float>;

}  // namespace mvtwin::forward
