#include "mvtwin/forward/symmetric_block_matrix.h"

#include <algorithm>
#include <string>

#include "mvtwin/core/error.h"

namespace mvtwin::forward {

SymmetricBlockMatrix::SymmetricBlockMatrix(const std::vector<char>& node_free,
                                           const std::vector<std::vector<int>>& cliques) {
  const int n = static_cast<int>(node_free.size());
  first_row_.assign(n, -1);
  int rows = 0;
  for (int i = 0; i < n; ++i) {
    if (node_free[i]) {
      first_row_[i] = rows;
      rows += 3;
    }
  }
  // Coupled free nodes of each free node, below it in row order (and itself).
  std::vector<std::vector<int>> below(n);
  for (const auto& c : cliques) {
    for (int a : c) {
      if (a < 0 || a >= n) throw Error("symmetric block matrix: clique node out of range");
    }
  }
  for (const auto& c : cliques) {
    for (int a : c) {
      if (first_row_[a] < 0) continue;
      for (int b : c) {
        if (first_row_[b] >= 0 && first_row_[b] <= first_row_[a]) below[b].push_back(a);
      }
    }
  }
  // Column-major lower triangle: column of node b, dof s holds rows first_row(a) + r >= its own.
  std::vector<int> outer(static_cast<size_t>(rows) + 1, 0);
  std::vector<int> inner;
  std::vector<std::vector<int>> block_start(n);  // per node b: value index of a's rows, col s=0
  std::vector<int> order;
  for (int b = 0; b < n; ++b) {
    if (first_row_[b] < 0) continue;
    auto& list = below[b];
    std::sort(list.begin(), list.end(),
              [&](int p, int q) { return first_row_[p] < first_row_[q]; });
    list.erase(std::unique(list.begin(), list.end()), list.end());
    for (int s = 0; s < 3; ++s) {
      const int col = first_row_[b] + s;
      outer[col] = static_cast<int>(inner.size());
      for (int a : list) {
        for (int r = (a == b ? s : 0); r < 3; ++r) inner.push_back(first_row_[a] + r);
      }
    }
  }
  outer[rows] = static_cast<int>(inner.size());
  lower_.resize(rows, rows);
  lower_.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
  std::copy(outer.begin(), outer.end(), lower_.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), lower_.innerIndexPtr());
  lower_.makeCompressed();
  set_zero();

  // Slot of the first stored row of node a in column (b, s): binary search in the column.
  auto find_slot = [&](int a, int b, int s) {
    const int col = first_row_[b] + s;
    const int row = first_row_[a] + (a == b ? s : 0);
    const int* begin = inner.data() + outer[col];
    const int* end = inner.data() + outer[col + 1];
    const int* it = std::lower_bound(begin, end, row);
    if (it == end || *it != row) throw Error("symmetric block matrix: pattern lookup failed");
    return static_cast<int>(it - inner.data());
  };
  clique_start_.push_back(0);
  for (const auto& c : cliques) {
    const int m = static_cast<int>(c.size());
    slot_start_.push_back(static_cast<int>(slots_.size()));
    clique_nodes_.insert(clique_nodes_.end(), c.begin(), c.end());
    clique_start_.push_back(static_cast<int>(clique_nodes_.size()));
    slots_.resize(slots_.size() + static_cast<size_t>(m) * m * 3, -1);
    const int ci = static_cast<int>(clique_start_.size()) - 2;
    for (int i = 0; i < m; ++i) {
      for (int j = 0; j < m; ++j) {
        const int a = c[i], b = c[j];
        if (first_row_[a] < 0 || first_row_[b] < 0) continue;
        if (a != b && first_row_[a] < first_row_[b]) continue;
        for (int s = 0; s < 3; ++s) slot(ci, i, j, s) = find_slot(a, b, s);
      }
    }
  }
  diagonal_slot_.assign(static_cast<size_t>(rows), -1);
  for (int b = 0; b < n; ++b) {
    if (first_row_[b] < 0) continue;
    // The node's own diagonal block is always in the pattern (it is in the list of itself only
    // when it belongs to a clique; add it otherwise).
    bool has = std::binary_search(below[b].begin(), below[b].end(), b,
                                  [&](int p, int q) { return first_row_[p] < first_row_[q]; });
    if (!has) {
      throw Error("symmetric block matrix: free node " + std::to_string(b) +
                  " belongs to no clique");
    }
    for (int s = 0; s < 3; ++s) diagonal_slot_[first_row_[b] + s] = find_slot(b, b, s);
  }
}

void SymmetricBlockMatrix::set_zero() {
  std::fill(lower_.valuePtr(), lower_.valuePtr() + lower_.nonZeros(), 0.0);
}

void SymmetricBlockMatrix::add_clique(int c, const Eigen::Ref<const Eigen::MatrixXd>& K, double s) {
  const int m = clique_start_[c + 1] - clique_start_[c];
  double* values = lower_.valuePtr();
  for (int j = 0; j < m; ++j) {
    for (int i = 0; i < m; ++i) {
      for (int col = 0; col < 3; ++col) {
        const int k = slot(c, i, j, col);
        if (k < 0) continue;
        // Same node: rows col..2 of the block; otherwise all three.
        const bool same =
            clique_nodes_[clique_start_[c] + i] == clique_nodes_[clique_start_[c] + j];
        for (int r = same ? col : 0, q = 0; r < 3; ++r, ++q)
          values[k + q] += s * K(3 * i + r, 3 * j + col);
      }
    }
  }
}

void SymmetricBlockMatrix::add_diagonal_block(int node, const Eigen::Matrix3d& B) {
  const int f = first_row_[node];
  if (f < 0) return;
  double* values = lower_.valuePtr();
  for (int col = 0; col < 3; ++col) {
    const int k = diagonal_slot_[f + col];
    for (int r = col, q = 0; r < 3; ++r, ++q) values[k + q] += B(r, col);
  }
}

void SymmetricBlockMatrix::add_diagonal(const Eigen::VectorXd& d) {
  double* values = lower_.valuePtr();
  for (int i = 0; i < num_nodes(); ++i) {
    const int f = first_row_[i];
    if (f < 0) continue;
    for (int s = 0; s < 3; ++s) values[diagonal_slot_[f + s]] += d[i];
  }
}

void SymmetricBlockMatrix::multiply(const Eigen::VectorXd& x, Eigen::VectorXd* y) const {
  *y = lower_.selfadjointView<Eigen::Lower>() * x;
}

}  // namespace mvtwin::forward
