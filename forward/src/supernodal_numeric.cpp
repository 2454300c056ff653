#include "supernodal_numeric.h"

#include <algorithm>
#include <cstddef>
#include <type_traits>

#include <cholmod.h>
#include <dlfcn.h>

#include "run_both.h"

namespace {

// BLAS and LAPACK as the process has them: the library CHOLMOD calls (OpenBLAS here, through
// Debian's libblas.so.3 / liblapack.so.3 alternatives), looked up at run time rather than
// linked, so that the link cannot pick another BLAS (ATLAS's development links, 2x slower
// here). gfortran's hidden string lengths are passed explicitly.
template <typename T>
struct Lapack {
  using Gemm = void (*)(const char*, const char*, const int*, const int*, const int*, const T*,
                        const T*, const int*, const T*, const int*, const T*, T*, const int*,
                        std::size_t, std::size_t);
  using Trsm = void (*)(const char*, const char*, const char*, const char*, const int*, const int*,
                        const T*, const T*, const int*, T*, const int*, std::size_t, std::size_t,
                        std::size_t, std::size_t);
  using Potrf = void (*)(const char*, const int*, T*, const int*, int*, std::size_t);
  Gemm gemm = nullptr;
  Trsm trsm = nullptr;
  Potrf potrf = nullptr;
  bool ok() const { return gemm && trsm && potrf; }
};
template <typename T>
const Lapack<T>& lapack() {
  static const Lapack<T> l = [] {
    constexpr bool single = std::is_same_v<T, float>;
    Lapack<T> r;
    r.gemm = reinterpret_cast<typename Lapack<T>::Gemm>(
        dlsym(RTLD_DEFAULT, single ? "sgemm_" : "dgemm_"));
    r.trsm = reinterpret_cast<typename Lapack<T>::Trsm>(
        dlsym(RTLD_DEFAULT, single ? "strsm_" : "dtrsm_"));
    r.potrf = reinterpret_cast<typename Lapack<T>::Potrf>(
        dlsym(RTLD_DEFAULT, single ? "spotrf_" : "dpotrf_"));
    return r;
  }();
  return l;
}

}  // namespace

namespace mvtwin::forward {

bool SupernodalStructure::set(const cholmod_factor_struct* L) {
  if (!L || !L->is_super || L->itype != CHOLMOD_INT || !L->super || !L->pi || !L->px || !L->s ||
      !L->Perm)
    return false;
  n = static_cast<int>(L->n);
  const int ns = static_cast<int>(L->nsuper);
  auto ints = [](const void* p, size_t count) {
    const int* q = static_cast<const int*>(p);
    return std::vector<int>(q, q + count);
  };
  super = ints(L->super, ns + 1);
  pi = ints(L->pi, ns + 1);
  px = ints(L->px, ns + 1);
  s = ints(L->s, L->ssize);
  perm = ints(L->Perm, L->n);
  xsize = L->xsize;

  // The elimination tree of the supernodes and each subtree's work (factor entries).
  super_of.assign(n, 0);
  parent.assign(ns, -1);
  for (int k = 0; k < ns; ++k)
    for (int c = super[k]; c < super[k + 1]; ++c) super_of[c] = k;
  std::vector<std::vector<int>> children(ns);
  std::vector<int> candidates;
  std::vector<double> work(ns), subtree(ns, 0.0);
  for (int k = 0; k < ns; ++k) {
    const int nc = super[k + 1] - super[k], nr = pi[k + 1] - pi[k];
    work[k] = static_cast<double>(nr) * nc;
    if (nr > nc) {
      parent[k] = super_of[s[pi[k] + nc]];
      children[parent[k]].push_back(k);
    } else {
      candidates.push_back(k);  // a root
    }
  }
  for (int k = 0; k < ns; ++k) {  // children come before their parents
    subtree[k] += work[k];
    if (parent[k] >= 0) subtree[parent[k]] += subtree[k];
  }
  // The split: starting from the roots, the candidate subtree of most work is repeatedly
  // replaced by its children (its supernode joins the top), and the candidates are dealt,
  // largest first, to the lighter of two groups; of all the splits tried, the one with the
  // least work on the critical path (top + heavier group) is kept.
  double top_work = 0.0, best = 0.0;
  std::vector<int> best_candidates, best_assign;
  for (int round = 0; round < 256 && !candidates.empty(); ++round) {
    std::vector<int> order(candidates.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return subtree[candidates[a]] > subtree[candidates[b]]; });
    double load[2] = {0.0, 0.0};
    std::vector<int> assign(candidates.size());
    for (int i : order) {
      const int g = load[1] < load[0] ? 1 : 0;
      assign[i] = g;
      load[g] += subtree[candidates[i]];
    }
    const double cost = top_work + std::max(load[0], load[1]);
    if (best_assign.empty() || cost < best) {
      best = cost;
      best_candidates = candidates;
      best_assign = assign;
    }
    const int c = candidates[order[0]];  // open up the largest candidate
    if (children[c].empty()) break;
    candidates.erase(candidates.begin() + order[0]);
    candidates.insert(candidates.end(), children[c].begin(), children[c].end());
    top_work += work[c];
  }
  // Every supernode below a candidate joins its group; the others make the top.
  group_of.assign(ns, -1);
  for (size_t i = 0; i < best_candidates.size(); ++i) group_of[best_candidates[i]] = best_assign[i];
  for (int k = ns - 1; k >= 0; --k)
    if (group_of[k] < 0 && parent[k] >= 0 && group_of[parent[k]] >= 0)
      group_of[k] = group_of[parent[k]];
  column_group.assign(n, -1);
  for (auto& part : parts) part.clear();
  top_columns.clear();
  for (int k = 0; k < ns; ++k) {
    parts[group_of[k] < 0 ? 2 : group_of[k]].push_back(k);
    for (int c = super[k]; c < super[k + 1]; ++c) {
      column_group[c] = group_of[k];
      if (group_of[k] < 0) top_columns.push_back(c);
    }
  }
  return true;
}

template <typename Scalar>
bool SupernodalNumeric<Scalar>::prepare(const SupernodalStructure& st,
                                        const Eigen::SparseMatrix<double>& A) {
  st_ = nullptr;
  if (!lapack<Scalar>().ok()) return false;
  const int n = st.n, ns = st.num_supernodes();
  if (A.rows() != n || A.cols() != n || !A.isCompressed()) return false;
  for (int k = 0; k < ns; ++k) {  // each supernode's rows ascending
    for (int p = st.pi[k] + 1; p < st.pi[k + 1]; ++p)
      if (st.s[p] <= st.s[p - 1]) return false;
  }
  std::vector<int> ip(n);
  for (int k = 0; k < n; ++k) ip[st.perm[k]] = k;
  const int* outer = A.outerIndexPtr();
  const int* inner = A.innerIndexPtr();
  dest_.resize(static_cast<size_t>(A.nonZeros()));
  for (int c = 0; c < n; ++c) {
    for (int k = outer[c]; k < outer[c + 1]; ++k) {
      const int i = ip[inner[k]], j = ip[c];
      const int row = std::max(i, j), col = std::min(i, j);
      const int sn = st.super_of[col];
      const int* first = st.s.data() + st.pi[sn];
      const int* last = st.s.data() + st.pi[sn + 1];
      const int* at = std::lower_bound(first, last, row);
      if (at == last || *at != row) return false;
      const size_t nr = static_cast<size_t>(last - first);
      dest_[static_cast<size_t>(k)] = static_cast<size_t>(st.px[sn]) +
                                      static_cast<size_t>(col - st.super[sn]) * nr +
                                      static_cast<size_t>(at - first);
    }
  }
  x_.assign(st.xsize, Scalar(0));
  next_.assign(ns, 0);
  for (auto& p : pending_) p.assign(ns, {});
  st_ = &st;
  return true;
}

template <typename Scalar>
bool SupernodalNumeric<Scalar>::factorize(const Eigen::SparseMatrix<double>& A, int threads) {
  if (!st_ || static_cast<size_t>(A.nonZeros()) != dest_.size()) return false;
  const SupernodalStructure& st = *st_;
  std::fill(x_.begin(), x_.end(), Scalar(0));
  const double* a = A.valuePtr();
  for (size_t k = 0; k < dest_.size(); ++k) x_[dest_[k]] += static_cast<Scalar>(a[k]);
  for (auto& p : pending_)
    for (auto& list : p) list.clear();
  bool ok[3] = {true, true, true};
  auto part = [&](int g) {
    std::vector<int> map(static_cast<size_t>(st.n));
    for (int j : st.parts[g]) {
      if (!factorize_supernode(j, g, &map)) {
        ok[g] = false;
        return;
      }
    }
  };
  run_both(
      threads, [&] { part(0); }, [&] { part(1); });
  if (!ok[0] || !ok[1]) return false;
  part(2);
  return ok[2];
}

// Left-looking: supernode j receives the updates of every descendant d whose next rows fall in
// its columns (C = L_d[p1:, :] L_d[p1:p2, :]^T, scattered into j's block), is factorized
// (potrf on its diagonal block, trsm below it), and is queued at the supernode of its first
// row below its own columns. `context` is the part running (0, 1: a group; 2: the top): a part
// queues only in its own lists, which the top reads in the order 0, 1, 2.
template <typename Scalar>
bool SupernodalNumeric<Scalar>::factorize_supernode(int j, int context, std::vector<int>* map) {
  const SupernodalStructure& st = *st_;
  thread_local std::vector<Scalar> C;
  const int k1 = st.super[j], k2 = st.super[j + 1], nc = k2 - k1, nr = st.pi[j + 1] - st.pi[j];
  Scalar* Lj = x_.data() + st.px[j];
  const int* Rj = st.s.data() + st.pi[j];
  for (int i = 0; i < nr; ++i) (*map)[Rj[i]] = i;
  const Scalar one = 1, zero = 0;
  for (int g = 0; g < 3; ++g) {
    if (g != context && context != 2) continue;  // a group's supernode hears its own group only
    for (int d : pending_[g][j]) {
      const int ndcol = st.super[d + 1] - st.super[d], ndrow = st.pi[d + 1] - st.pi[d];
      const int* Rd = st.s.data() + st.pi[d];
      const Scalar* Ld = x_.data() + st.px[d];
      const int p1 = next_[d];
      int p2 = p1;
      while (p2 < ndrow && Rd[p2] < k2) ++p2;
      const int m1 = p2 - p1, m2 = ndrow - p1;
      C.resize(static_cast<size_t>(m2) * m1);
      lapack<Scalar>().gemm("N", "T", &m2, &m1, &ndcol, &one, Ld + p1, &ndrow, Ld + p1, &ndrow,
                            &zero, C.data(), &m2, 1, 1);
      for (int c = 0; c < m1; ++c) {
        Scalar* col = Lj + static_cast<size_t>(Rd[p1 + c] - k1) * nr;
        const Scalar* cc = C.data() + static_cast<size_t>(c) * m2;
        for (int r = c; r < m2; ++r) col[(*map)[Rd[p1 + r]]] -= cc[r];
      }
      if (p2 < ndrow) {
        next_[d] = p2;
        pending_[context][st.super_of[Rd[p2]]].push_back(d);
      }
    }
  }
  int info = 0;
  lapack<Scalar>().potrf("L", &nc, Lj, &nr, &info, 1);
  if (info != 0) return false;
  if (nr > nc) {
    const int m = nr - nc;
    lapack<Scalar>().trsm("R", "L", "T", "N", &m, &nc, &one, Lj, &nr, Lj + nc, &nr, 1, 1, 1, 1);
    next_[j] = nc;
    pending_[context][st.super_of[Rj[nc]]].push_back(j);
  }
  return true;
}

template class SupernodalNumeric<double>;
template class SupernodalNumeric<float>;

}  // namespace mvtwin::forward
