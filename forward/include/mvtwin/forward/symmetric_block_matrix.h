#pragma once
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace mvtwin::forward {

/// The lower triangle of a symmetric sparse matrix over the free degrees of freedom of a set of
/// nodes (3 per node), on a pattern fixed at construction.
///
/// Every two nodes of a clique (an element, the insertion nodes of a chorda) are coupled. The
/// compressed storage is built once; assembly adds 3x3 node blocks straight into its values
/// through precomputed slots (no triplets, no sorting), so that a factorization's symbolic
/// analysis is done once per simulation and assembly costs little more than the element work.
///
///   node_free   #nodes flags: 1 when the node's three dofs are unknowns (prescribed: 0)
///   cliques     lists of node indices; clique c couples all pairs of its nodes
class SymmetricBlockMatrix {
 public:
  SymmetricBlockMatrix(const std::vector<char>& node_free,
                       const std::vector<std::vector<int>>& cliques);

  /// Number of unknowns (3 per free node).
  int rows() const { return static_cast<int>(lower_.rows()); }
  int num_nodes() const { return static_cast<int>(first_row_.size()); }
  /// First row of a free node's three unknowns, or -1 for a prescribed node.
  int first_row(int node) const { return first_row_[node]; }

  void set_zero();
  /// Adds s x K to the matrix; K is 3n x 3n over the n nodes of clique c in their listed order
  /// and symmetric (only the blocks that land in the lower triangle are read).
  void add_clique(int c, const Eigen::Ref<const Eigen::MatrixXd>& K, double s);
  /// Adds a symmetric 3x3 block on a node's diagonal (ignored for prescribed nodes).
  void add_diagonal_block(int node, const Eigen::Matrix3d& B);
  /// Adds d[node] to the three diagonal entries of each free node.
  void add_diagonal(const Eigen::VectorXd& d);

  /// The lower triangle (column major), for a factorization.
  const Eigen::SparseMatrix<double>& lower() const { return lower_; }
  /// y = A x (the full symmetric matrix), x and y over the free rows.
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd* y) const;

 private:
  // Value index of the first stored row of block (a, b) in column first_row(b) + s, for the
  // clique's ordered node pairs (a, b) with first_row(a) > first_row(b) or a == b; -1 otherwise.
  int& slot(int c, int i, int j, int s) {
    const int n = clique_start_[c + 1] - clique_start_[c];
    return slots_[slot_start_[c] + (i * n + j) * 3 + s];
  }
  int slot(int c, int i, int j, int s) const {
    const int n = clique_start_[c + 1] - clique_start_[c];
    return slots_[slot_start_[c] + (i * n + j) * 3 + s];
  }

  Eigen::SparseMatrix<double> lower_;
  std::vector<int> first_row_;
  std::vector<int> clique_start_, clique_nodes_, slot_start_, slots_;
  std::vector<int> diagonal_slot_;  // per free node and column s: value index of row (3n + s)
};

}  // namespace mvtwin::forward
