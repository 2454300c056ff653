#include "mvtwin/forward/step_solver.h"

#include "mvtwin/core/error.h"
#include "mvtwin/core/stopwatch.h"
#include "run_both.h"
#include "supernodal_numeric.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <chrono>

#include <dlfcn.h>
#include <malloc.h>
#include <omp.h>
#include <mutex>
#include <type_traits>
#include <vector>

#include <Eigen/CholmodSupport>
#include <Eigen/Dense>
#include <Eigen/SparseCholesky>

namespace mvtwin::forward {

const char* name(LinearSolver s) {
  switch (s) {
    case LinearSolver::kCholmodSupernodal:
      return "cholmod-supernodal";
    case LinearSolver::kCholmodSimplicial:
      return "cholmod-simplicial";
    case LinearSolver::kEigenLdlt:
      return "eigen-ldlt";
    case LinearSolver::kReusedFactorPcg:
      return "reused-factor-pcg";
  }
  return "?";
}

bool parse_linear_solver(const std::string& text, LinearSolver* out) {
  for (LinearSolver s : {LinearSolver::kCholmodSupernodal, LinearSolver::kCholmodSimplicial,
                         LinearSolver::kEigenLdlt, LinearSolver::kReusedFactorPcg}) {
    if (text == name(s)) {
      *out = s;
      return true;
    }
  }
  return false;
}

namespace {

using Clock = std::chrono::steady_clock;

/// CHOLMOD (SuiteSparse 5) runs parallel loops with a compiled-in 4 OpenMP threads; on this
/// machine's 2 cores, and beside parallel candidate simulations, they only contend. A
/// max-active-levels of 0 makes every parallel region of this thread run serially.
///
/// The BLAS under CHOLMOD is called from several threads at once when candidate simulations run
/// in parallel. OpenBLAS's serial build is not safe for that (its buffers are shared without
/// locks: concurrent closures gave different numbers); its threaded build is, and is told here
/// to use one thread per call, so that a simulation stays on one core.
void serial_openmp() {
  omp_set_max_active_levels(0);
  static const bool blas_single_threaded = [] {
    using SetThreads = void (*)(int);
    if (auto* f = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads")))
      f(1);
    return true;
  }();
  (void)blas_single_threaded;
}

/// Every CHOLMOD factorization allocates its workspace afresh and frees it after; above
/// glibc's mmap threshold that memory went back to the system each time and came back as page
/// faults on the next factorization (28 % of a closure's page faults; on this VM a page fault
/// is expensive). Freed blocks up to 32 MB (glibc's largest threshold; the paper's grid's factor
/// is 2.5 M entries, 20 MB in double) now stay in the process's heap for reuse. Measured: closure
/// at the paper's grid, dt 0.02 s, 1.73 -> 1.54 s. Process-wide and once; the memory kept is
/// bounded by the peak.
void keep_freed_memory() {
  static std::once_flag once;
  std::call_once(once, [] {
    mallopt(M_MMAP_THRESHOLD, 32 << 20);
    mallopt(M_TRIM_THRESHOLD, 256 << 20);
  });
}

/// A direct factorization whose symbolic analysis is redone only when the pattern changes.
class Factor {
 public:
  virtual ~Factor() = default;
  bool factorize(const Eigen::SparseMatrix<double>& A, StepSolver::Stats* st) {
    const bool same =
        A.rows() == rows_ && A.nonZeros() == static_cast<Eigen::Index>(inner_.size()) &&
        std::memcmp(A.outerIndexPtr(), outer_.data(), outer_.size() * sizeof(int)) == 0 &&
        std::memcmp(A.innerIndexPtr(), inner_.data(), inner_.size() * sizeof(int)) == 0;
    if (!same) {
      serial_openmp();
      rows_ = A.rows();
      outer_.assign(A.outerIndexPtr(), A.outerIndexPtr() + A.outerSize() + 1);
      inner_.assign(A.innerIndexPtr(), A.innerIndexPtr() + A.nonZeros());
      const auto t0 = Clock::now();
      if (analyze(A)) ++st->orderings_reused;
      ++st->analyses;
      st->analyze_s += seconds_since(t0);
    }
    ++st->factorizations;
    serial_openmp();
    const bool ok = numeric(A);
    st->double_fallbacks = double_fallbacks;
    return ok;
  }
  virtual Eigen::VectorXd apply(const Eigen::VectorXd& b) const = 0;
  /// Threads of the supernodal single-precision factorization and substitutions (1 or 2).
  int threads = 1;
  int double_fallbacks = 0;  ///< single-precision factorizations redone in double

 protected:
  /// The symbolic analysis; true when it reused an ordering found earlier in the process.
  virtual bool analyze(const Eigen::SparseMatrix<double>& A) = 0;
  virtual bool numeric(const Eigen::SparseMatrix<double>& A) = 0;

 private:
  Eigen::Index rows_ = -1;
  std::vector<int> outer_, inner_;
};

/// Eigen's CHOLMOD supernodal LL^T with access to CHOLMOD's factor.
class SupernodalLLT
    : public Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> {
 public:
  const cholmod_factor* factor() const { return m_cholmodFactor; }

  /// analyzePattern with the fill-reducing permutation given: no ordering is tried and the
  /// permutation is kept as it is (no postordering: a permutation taken from a factor is
  /// postordered already), so the factor's structure is the one that permutation gave before.
  void analyze_given(const Eigen::SparseMatrix<double>& A, std::vector<int> perm) {
    if (m_cholmodFactor) {
      cholmod_free_factor(&m_cholmodFactor, &cholmod());
      m_cholmodFactor = nullptr;
    }
    cholmod_sparse a = Eigen::viewAsCholmod(A.selfadjointView<Eigen::Lower>());
    const int nmethods = cholmod().nmethods, ordering = cholmod().method[0].ordering;
    const int postorder = cholmod().postorder;
    cholmod().nmethods = 1;
    cholmod().method[0].ordering = CHOLMOD_GIVEN;
    cholmod().postorder = 0;
    m_cholmodFactor = cholmod_analyze_p(&a, perm.data(), nullptr, 0, &cholmod());
    cholmod().nmethods = nmethods;
    cholmod().method[0].ordering = ordering;
    cholmod().postorder = postorder;
    m_isInitialized = true;
    m_info = m_cholmodFactor ? Eigen::Success : Eigen::NumericalIssue;
    m_analysisIsOk = m_cholmodFactor != nullptr;
    m_factorizationIsOk = false;
  }
};

/// The fill-reducing orderings found in this process, by sparsity pattern (the last few). A
/// calibration or a study simulates the same model many times: its step matrix's pattern is the
/// same every time, and choosing its ordering (AMD, METIS and nested dissection tried) is most
/// of a symbolic analysis. The ordering is a function of the pattern alone (METIS is seeded the
/// same on every call), so reusing it gives the factor a fresh analysis would give.
class OrderingCache {
 public:
  static constexpr size_t kEntries = 4;
  /// The ordering of A's pattern, or nullptr.
  const std::vector<int>* find(const Eigen::SparseMatrix<double>& A) const {
    for (const Entry& e : entries_) {
      if (e.rows == A.rows() && e.inner.size() == static_cast<size_t>(A.nonZeros()) &&
          std::equal(e.outer.begin(), e.outer.end(), A.outerIndexPtr()) &&
          std::equal(e.inner.begin(), e.inner.end(), A.innerIndexPtr()))
        return &e.perm;
    }
    return nullptr;
  }
  void store(const Eigen::SparseMatrix<double>& A, const cholmod_factor* L) {
    if (!L || !L->Perm || L->itype != CHOLMOD_INT) return;
    if (entries_.size() == kEntries) entries_.erase(entries_.begin());
    const int* perm = static_cast<const int*>(L->Perm);
    entries_.push_back({A.rows(),
                        {A.outerIndexPtr(), A.outerIndexPtr() + A.outerSize() + 1},
                        {A.innerIndexPtr(), A.innerIndexPtr() + A.nonZeros()},
                        {perm, perm + L->n}});
  }

 private:
  struct Entry {
    Eigen::Index rows;
    std::vector<int> outer, inner, perm;
  };
  std::vector<Entry> entries_;
};

/// A single-precision copy of a supernodal LL^T factor (L L^T = P A P^T), solved by its own
/// supernodal forward and backward substitution. As a preconditioner it needs no double
/// precision, and a triangular solve reads the whole factor twice, memory-bound: floats halve
/// the traffic.
///
/// The substitutions run in two parts at once (run_both) over the structure's split of the
/// elimination tree (SupernodalStructure: two groups of whole subtrees and the top above them):
/// the forward solve does both groups at once and the top after them, the backward solve the
/// top first and both groups at once after it. A group's updates of top rows go to its own buffer,
/// added to the top rows in a fixed order (group 0, then 1) whatever the number of threads, so that
/// the preconditioner, and so the simulation, is the same bit for bit on one thread or two.
class FloatSupernodal {
 public:
  /// The factor with structure st (which must outlive this) and values x.
  void set(const SupernodalStructure& st, const double* x) {
    st_ = &st;
    own_.resize(st.xsize);
    for (size_t i = 0; i < st.xsize; ++i) own_[i] = static_cast<float>(x[i]);
    x_ = own_.data();
  }
  /// The factor's values in single precision already (x must outlive this, unchanged).
  void set(const SupernodalStructure& st, const float* x) {
    st_ = &st;
    x_ = x;
  }
  Eigen::VectorXd solve(const Eigen::VectorXd& b, int threads) const {
    const int n = st_->n;
    Eigen::VectorXf y(n);
    for (int k = 0; k < n; ++k) y[k] = static_cast<float>(b[st_->perm[k]]);
    // L y = P b: both groups (their updates of top rows into their buffers), then the top.
    Eigen::VectorXf buffer[2];
    auto forward_group = [&](int g) {
      buffer[g].setZero(n);
      for (int s : st_->parts[g]) forward(s, &y, g, &buffer[g]);
    };
    run_both(
        threads, [&] { forward_group(0); }, [&] { forward_group(1); });
    for (int r : st_->top_columns) y[r] = (y[r] + buffer[0][r]) + buffer[1][r];
    for (int s : st_->parts[2]) forward(s, &y, -1, nullptr);
    // L^T x' = y: the top, then both groups (reading top rows, writing their own).
    const std::vector<int>& top = st_->parts[2];
    for (auto it = top.rbegin(); it != top.rend(); ++it) backward(*it, &y);
    auto backward_group = [&](int g) {
      const std::vector<int>& part = st_->parts[g];
      for (auto it = part.rbegin(); it != part.rend(); ++it) backward(*it, &y);
    };
    run_both(
        threads, [&] { backward_group(0); }, [&] { backward_group(1); });
    Eigen::VectorXd out(n);
    for (int k = 0; k < n; ++k) out[st_->perm[k]] = static_cast<double>(y[k]);
    return out;
  }

 private:
  using Block = Eigen::Map<const Eigen::MatrixXf>;
  // Supernode s of the forward substitution, in group g: its updates of rows outside the group
  // (the top's) go to *buf (g < 0: s is in the top, and so are all its rows).
  void forward(int s, Eigen::VectorXf* y, int g, Eigen::VectorXf* buf) const {
    const SupernodalStructure& st = *st_;
    const int k1 = st.super[s], nc = st.super[s + 1] - k1, nr = st.pi[s + 1] - st.pi[s];
    const Block Ls(x_ + st.px[s], nr, nc);
    auto y1 = y->segment(k1, nc);
    Ls.topRows(nc).triangularView<Eigen::Lower>().solveInPlace(y1);
    if (nr > nc) {
      const Eigen::VectorXf t = Ls.bottomRows(nr - nc) * y1;
      const int* rows = st.s.data() + st.pi[s] + nc;
      for (int i = 0; i < nr - nc; ++i) {
        if (g < 0 || st.column_group[rows[i]] == g)
          (*y)[rows[i]] -= t[i];
        else
          (*buf)[rows[i]] -= t[i];
      }
    }
  }
  void backward(int s, Eigen::VectorXf* y) const {
    const SupernodalStructure& st = *st_;
    const int k1 = st.super[s], nc = st.super[s + 1] - k1, nr = st.pi[s + 1] - st.pi[s];
    const Block Ls(x_ + st.px[s], nr, nc);
    auto y1 = y->segment(k1, nc);
    if (nr > nc) {
      Eigen::VectorXf t(nr - nc);
      const int* rows = st.s.data() + st.pi[s] + nc;
      for (int i = 0; i < nr - nc; ++i) t[i] = (*y)[rows[i]];
      y1.noalias() -= Ls.bottomRows(nr - nc).transpose() * t;
    }
    Ls.topRows(nc).triangularView<Eigen::Lower>().transpose().solveInPlace(y1);
  }

  const SupernodalStructure* st_ = nullptr;
  std::vector<float> own_;  // a copy rounded from double, when x_ points here
  const float* x_ = nullptr;
};

template <typename Solver>
class FactorOf : public Factor {
 public:
  Eigen::VectorXd apply(const Eigen::VectorXd& b) const override {
    serial_openmp();
    return s_.solve(b);
  }

 protected:
  bool analyze(const Eigen::SparseMatrix<double>& A) override {
    if constexpr (requires { s_.cholmod(); }) {
      // AMD, METIS and CHOLMOD's nested dissection tried, the ordering with the least fill
      // kept (on the 30 x 30 valve: flops 6.7e8 / 5.6e8 / 5.2e8). The pattern is fixed over a
      // run, so this is paid once (~0.1 s).
      s_.cholmod().nmethods = 3;
      s_.cholmod().method[0].ordering = CHOLMOD_AMD;
      s_.cholmod().method[1].ordering = CHOLMOD_METIS;
      s_.cholmod().method[2].ordering = CHOLMOD_NESDIS;
    }
    // METIS (behind CHOLMOD's METIS and NESDIS orderings) draws from a random generator
    // whose state is shared by the whole process: two simulations ordering at once in
    // different threads got different orderings, and so different round-off. One analysis at
    // a time keeps every simulation's numbers independent of what runs beside it.
    static std::mutex analysis_mutex;
    std::lock_guard<std::mutex> lock(analysis_mutex);
    if constexpr (std::is_same_v<Solver, SupernodalLLT>) {
      static OrderingCache orderings;  // guarded by analysis_mutex
      if (const std::vector<int>* perm = orderings.find(A)) {
        s_.analyze_given(A, *perm);
        return true;
      }
      s_.analyzePattern(A);
      orderings.store(A, s_.factor());
      return false;
    }
    s_.analyzePattern(A);
    return false;
  }
  bool numeric(const Eigen::SparseMatrix<double>& A) override {
    s_.factorize(A);
    return s_.info() == Eigen::Success;
  }

 public:
  Solver s_;
};

/// CHOLMOD supernodal, optionally applied as a preconditioner in single precision. With the
/// single-precision preconditioner the numeric factorization is SupernodalNumeric's (its two
/// groups at once with two threads) on CHOLMOD's symbolic analysis, in single precision with
/// single_precision_factorization (CHOLMOD's, applied in double, for a matrix that is not
/// positive definite in single precision); CHOLMOD's own otherwise, or should the structure not
/// hold the matrix.
class SupernodalFactor : public FactorOf<SupernodalLLT> {
 public:
  SupernodalFactor(bool single, bool single_factorization)
      : single_(single), single_factorization_(single && single_factorization) {}
  Eigen::VectorXd apply(const Eigen::VectorXd& b) const override {
    if (single_ && have_float_) return float_.solve(b, threads);
    return FactorOf<SupernodalLLT>::apply(b);
  }

 protected:
  bool analyze(const Eigen::SparseMatrix<double>& A) override {
    const bool reused = FactorOf<SupernodalLLT>::analyze(A);
    prepared_ = structured_ = own_ = false;
    return reused;
  }
  bool numeric(const Eigen::SparseMatrix<double>& A) override {
    have_float_ = false;
    if (single_ && !prepared_) {  // once per analysis: the structure, and whether ours fits
      prepared_ = true;
      structured_ = structure_.set(s_.factor());
      // Only the numeric factorization in use is prepared (each holds a whole factor).
      own_ = structured_ && (single_factorization_ ? single_numeric_.prepare(structure_, A)
                                                   : numeric_.prepare(structure_, A));
    }
    if (own_ && single_factorization_) {
      if (single_numeric_.factorize(A, threads)) {
        float_.set(structure_, single_numeric_.values().data());
        have_float_ = true;
        return true;
      }
      // Not positive definite in single precision: too ill-conditioned for a float
      // preconditioner at all, so CHOLMOD's double factor, applied in double.
      ++double_fallbacks;
      return FactorOf<SupernodalLLT>::numeric(A);
    }
    if (own_) {
      if (!numeric_.factorize(A, threads)) return false;
      float_.set(structure_, numeric_.values().data());
      have_float_ = true;
      return true;
    }
    const bool ok = FactorOf<SupernodalLLT>::numeric(A);
    if (ok && structured_ && s_.factor()->x) {
      float_.set(structure_, static_cast<const double*>(s_.factor()->x));
      have_float_ = true;
    }
    return ok;
  }

 private:
  bool single_, single_factorization_;
  bool have_float_ = false, prepared_ = false, structured_ = false, own_ = false;
  SupernodalStructure structure_;
  SupernodalNumeric<double> numeric_;
  SupernodalNumeric<float> single_numeric_;
  FloatSupernodal float_;
};

/// The combination x = sum c_i v_i that minimizes the energy norm of the error, (V^T A V) c =
/// V^T b, with its residual r = b - A x (Av holds A v_i). False when the projected matrix is
/// not positive definite (dependent or degenerate vectors).
bool galerkin(const std::vector<const Eigen::VectorXd*>& v,
              const std::vector<const Eigen::VectorXd*>& Av, const Eigen::VectorXd& b,
              Eigen::VectorXd* x, Eigen::VectorXd* r) {
  const int k = static_cast<int>(v.size());
  Eigen::MatrixXd G(k, k);
  Eigen::VectorXd rhs(k);
  for (int i = 0; i < k; ++i) {
    rhs[i] = v[i]->dot(b);
    for (int j = 0; j <= i; ++j) G(i, j) = G(j, i) = v[i]->dot(*Av[j]);
  }
  const Eigen::LLT<Eigen::MatrixXd> llt(G);
  if (llt.info() != Eigen::Success) return false;
  // Nearly dependent vectors: the smallest pivot against the largest diagonal entry.
  const Eigen::VectorXd d = llt.matrixLLT().diagonal();
  if (!(d.minCoeff() * d.minCoeff() > 1e-12 * G.diagonal().maxCoeff())) return false;
  const Eigen::VectorXd c = llt.solve(rhs);
  if (!c.allFinite()) return false;
  x->setZero(b.size());
  *r = b;
  for (int i = 0; i < k; ++i) {
    *x += c[i] * *v[i];
    *r -= c[i] * *Av[i];
  }
  return true;
}

constexpr int kMaxReuseBackoff = 8;  // solves factorized at once after repeated failed reuses

}  // namespace

struct StepSolver::Impl {
  std::unique_ptr<Factor> factor;
  bool have_factor = false;
  bool stale = false;
  // After a reused factor failed (iterate()): how many solves factorize at once before a reuse
  // is tried again, doubling with each failure up to kMaxReuseBackoff, 0 once a reuse serves.
  int reuse_backoff = 0, skip_reuse = 0;
};

bool StepSolverOptions::is_valid(std::string* error) const {
  if (!(pcg_tolerance > 0 && pcg_tolerance < 1)) {
    *error = "pcg_tolerance must be in (0, 1)";
    return false;
  }
  if (pcg_max_iterations < 1) {
    *error = "pcg_max_iterations must be >= 1";
    return false;
  }
  if (refactor_iterations < 1) {
    *error = "refactor_iterations must be >= 1";
    return false;
  }
  return true;
}

StepSolver::StepSolver(const StepSolverOptions& o) : impl_(std::make_unique<Impl>()), opt_(o) {
  if (std::string why; !o.is_valid(&why)) throw Error("step solver options: " + why);
  keep_freed_memory();
  switch (o.kind) {
    case LinearSolver::kCholmodSimplicial:
      impl_->factor = std::make_unique<
          FactorOf<Eigen::CholmodSimplicialLLT<Eigen::SparseMatrix<double>, Eigen::Lower>>>();
      break;
    case LinearSolver::kEigenLdlt:
      impl_->factor = std::make_unique<
          FactorOf<Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower>>>();
      break;
    case LinearSolver::kCholmodSupernodal:
    case LinearSolver::kReusedFactorPcg:
      impl_->factor = std::make_unique<SupernodalFactor>(o.single_precision_preconditioner,
                                                         o.single_precision_factorization);
      break;
  }
}

StepSolver::~StepSolver() = default;

void StepSolver::set_threads(int threads) { impl_->factor->threads = threads; }

bool StepSolver::factorize(const System& A, std::string* why) {
  const auto t0 = Clock::now();
  const bool ok = impl_->factor->factorize(A.lower(), &stats_);
  stats_.factorize_s += seconds_since(t0);
  impl_->stale = false;
  impl_->have_factor = ok;
  if (!ok) *why = "linear solver failed (matrix not positive definite)";
  return ok;
}

bool StepSolver::begin_solve(const Eigen::VectorXd& b, Eigen::VectorXd* x, std::string* why,
                             bool* done) {
  ++stats_.solves;
  *done = true;
  if (!b.allFinite()) {
    *why = "non-finite right-hand side";
    return false;
  }
  if (!(b.norm() > 0)) {
    *x = Eigen::VectorXd::Zero(b.size());
    return true;
  }
  *done = false;
  return true;
}

bool StepSolver::solve_nonsymmetric(const System& A, const Eigen::VectorXd& b, Eigen::VectorXd* x,
                                    std::string* why) {
  bool done = false;
  if (const bool ok = begin_solve(b, x, why, &done); done) return ok;
  const double bnorm = b.norm();
  bool fresh = false;
  if (!impl_->have_factor || impl_->stale || opt_.kind != LinearSolver::kReusedFactorPcg) {
    if (!factorize(A, why)) return false;
    fresh = true;
  }
  auto precondition = [&](const Eigen::VectorXd& r) {
    const auto t = Clock::now();
    ++stats_.applications;
    Eigen::VectorXd z = impl_->factor->apply(r);
    stats_.apply_s += seconds_since(t);
    return z;
  };
  const int m = opt_.pcg_max_iterations;
  const double target = opt_.pcg_tolerance * bnorm;
  // Flexible GMRES(m): the preconditioned directions Z are kept, so the update is sum y_j z_j.
  auto gmres = [&](Eigen::VectorXd* xk, int* iterations) {
    xk->setZero(b.size());
    Eigen::VectorXd r = b;
    *iterations = 0;
    for (int cycle = 0; cycle < 3 && r.norm() > target; ++cycle) {
      const double beta = r.norm();
      std::vector<Eigen::VectorXd> V{r / beta}, Z;
      Eigen::MatrixXd H = Eigen::MatrixXd::Zero(m + 1, m);
      Eigen::VectorXd g = Eigen::VectorXd::Zero(m + 1), cs(m), sn(m);
      g[0] = beta;
      int j = 0;
      for (; j < m; ++j) {
        ++*iterations;
        Z.push_back(precondition(V[j]));
        Eigen::VectorXd w;
        A.multiply(Z[j], &w);
        for (int i = 0; i <= j; ++i) {
          H(i, j) = w.dot(V[i]);
          w -= H(i, j) * V[i];
        }
        H(j + 1, j) = w.norm();
        for (int i = 0; i < j; ++i) {  // the earlier rotations on the new column
          const double t = cs[i] * H(i, j) + sn[i] * H(i + 1, j);
          H(i + 1, j) = -sn[i] * H(i, j) + cs[i] * H(i + 1, j);
          H(i, j) = t;
        }
        const double d = std::hypot(H(j, j), H(j + 1, j));
        cs[j] = d > 0 ? H(j, j) / d : 1.0;
        sn[j] = d > 0 ? H(j + 1, j) / d : 0.0;
        const double hj1 = H(j + 1, j);
        H(j, j) = d;
        H(j + 1, j) = 0.0;
        g[j + 1] = -sn[j] * g[j];
        g[j] = cs[j] * g[j];
        const bool reached = std::abs(g[j + 1]) <= target || !(hj1 > 1e-300 * beta);
        if (!reached) V.push_back(w / hj1);
        if (reached) {
          ++j;
          break;
        }
      }
      const Eigen::VectorXd y =
          H.topLeftCorner(j, j).triangularView<Eigen::Upper>().solve(g.head(j));
      for (int i = 0; i < j; ++i) *xk += y[i] * Z[i];
      Eigen::VectorXd Ax;
      A.multiply(*xk, &Ax);
      r = b - Ax;
    }
    stats_.pcg_iterations += *iterations;
    return r.norm() <= target && xk->allFinite();
  };
  return iterate(A, gmres, &fresh, x, why);
}

bool StepSolver::solve(const Eigen::SparseMatrix<double>& A, const Eigen::VectorXd& b,
                       Eigen::VectorXd* x, std::string* why) {
  Eigen::SparseMatrix<double> lower = A.triangularView<Eigen::Lower>();
  System s;
  s.multiply = [&A](const Eigen::VectorXd& v, Eigen::VectorXd* y) { *y = A * v; };
  s.lower = [&lower]() -> const Eigen::SparseMatrix<double>& { return lower; };
  return solve(s, b, x, why);
}

bool StepSolver::solve(const System& A, const Eigen::VectorXd& b, Eigen::VectorXd* x,
                       std::string* why) {
  bool done = false;
  if (const bool ok = begin_solve(b, x, why, &done); done) return ok;
  const double bnorm = b.norm();
  // Warm start: the best combination of the caller's guesses (earlier steps' updates) in A's
  // energy; the answer when it already meets the tolerance (no factorization, no preconditioner
  // application: the stale flag stays for the next solve).
  std::vector<const Eigen::VectorXd*> basis, Abasis;
  std::vector<Eigen::VectorXd> Aguesses;
  if (opt_.warm_start && A.guesses) {
    Aguesses.reserve(A.guesses->size());
    for (const Eigen::VectorXd& g : *A.guesses) {
      if (g.size() != b.size() || !g.allFinite()) continue;
      Aguesses.emplace_back();
      A.multiply(g, &Aguesses.back());
      // A guess without energy (zero) would make the projection singular and so discard the
      // others with it.
      if (!(g.dot(Aguesses.back()) > 0)) {
        Aguesses.pop_back();
        continue;
      }
      basis.push_back(&g);
      Abasis.push_back(&Aguesses.back());
    }
  }
  if (!basis.empty()) {
    ++stats_.warm_starts;
    Eigen::VectorXd xg, rg;
    if (galerkin(basis, Abasis, b, &xg, &rg) && rg.norm() <= opt_.pcg_tolerance * bnorm) {
      ++stats_.warm_accepted;
      *x = std::move(xg);
      return true;
    }
  }
  bool fresh = false;
  if (opt_.kind != LinearSolver::kReusedFactorPcg || !impl_->have_factor || impl_->stale) {
    if (!factorize(A, why)) return false;
    fresh = true;
  }
  // Preconditioned conjugate gradients on the exact operator. Right after a factorization the
  // preconditioner is A's factorized part itself and CG only has to account for the terms the
  // factorization leaves out (contact couplings); with a reused factor it also makes up for how
  // A has changed since.
  auto precondition = [&](const Eigen::VectorXd& r) {
    const auto t = Clock::now();
    ++stats_.applications;
    Eigen::VectorXd z;
    if (A.rotate && opt_.rotated_preconditioner && !fresh) {
      Eigen::VectorXd rr = r;
      A.rotate(&rr, true);
      z = impl_->factor->apply(rr);
      A.rotate(&z, false);
    } else {
      z = impl_->factor->apply(r);
    }
    stats_.apply_s += seconds_since(t);
    return z;
  };
  auto pcg = [&](Eigen::VectorXd* xk, int* iterations) {
    *xk = precondition(b);
    Eigen::VectorXd Ax;
    A.multiply(*xk, &Ax);
    Eigen::VectorXd r = b - Ax;
    if (!basis.empty() && r.norm() > opt_.pcg_tolerance * bnorm) {
      // The best combination of the preconditioned b and the guesses.
      std::vector<const Eigen::VectorXd*> v = basis, Av = Abasis;
      v.insert(v.begin(), xk);
      Av.insert(Av.begin(), &Ax);
      Eigen::VectorXd xc, rc;
      if (galerkin(v, Av, b, &xc, &rc) && rc.norm() < r.norm()) {
        *xk = std::move(xc);
        r = std::move(rc);
      }
    }
    *iterations = 0;
    if (r.norm() > opt_.pcg_tolerance * bnorm) {
      Eigen::VectorXd z = precondition(r);
      Eigen::VectorXd p = z, Ap;
      double rz = r.dot(z);
      while (*iterations < opt_.pcg_max_iterations && r.norm() > opt_.pcg_tolerance * bnorm) {
        ++*iterations;
        A.multiply(p, &Ap);
        const double pAp = p.dot(Ap);
        if (!(pAp > 0)) break;
        const double alpha = rz / pAp;
        *xk += alpha * p;
        r -= alpha * Ap;
        // Converged: the next direction (one more preconditioner application) is not needed.
        if (r.norm() <= opt_.pcg_tolerance * bnorm) break;
        z = precondition(r);
        const double rz_new = r.dot(z);
        p = z + (rz_new / rz) * p;
        rz = rz_new;
      }
    }
    stats_.pcg_iterations += *iterations;
    return r.norm() <= opt_.pcg_tolerance * bnorm && xk->allFinite();
  };
  return iterate(A, pcg, &fresh, x, why);
}

bool StepSolver::iterate(const System& A, const Iteration& run, bool* fresh, Eigen::VectorXd* x,
                         std::string* why) {
  Eigen::VectorXd xk;
  int iterations = 0;
  bool converged = run(&xk, &iterations);
  bool fell_back = false;
  if (!converged && !*fresh) {
    ++stats_.pcg_fallbacks;
    if (!factorize(A, why)) return false;
    *fresh = true;
    fell_back = true;
    converged = run(&xk, &iterations);
  }
  if (!xk.allFinite()) {
    *why = "linear solver returned non-finite values";
    return false;
  }
  if (!converged) {
    // A fresh factorization and the iteration cap were not enough (stiff couplings the
    // factorization leaves out): keep the last iterate, which the iteration has only improved,
    // and count it.
    ++stats_.unconverged;
  } else if (opt_.kind == LinearSolver::kReusedFactorPcg && !*fresh &&
             iterations >= opt_.refactor_iterations) {
    impl_->stale = true;
  }
  // A factor that could not serve this system (PCG ran to its cap and fell back to a new
  // factorization) will not serve the next ones either while the matrix changes that fast
  // (settling's long steps, where every other solve failed first): the next 1, 2, 4, ... (at
  // most kMaxReuseBackoff) solves factorize at once; a reuse that serves resets it.
  if (opt_.kind == LinearSolver::kReusedFactorPcg) {
    Impl& im = *impl_;
    if (fell_back) {
      im.reuse_backoff = std::clamp(2 * im.reuse_backoff, 1, kMaxReuseBackoff);
      im.skip_reuse = im.reuse_backoff;
    } else if (!*fresh) {
      im.reuse_backoff = 0;
    }
    if (im.skip_reuse > 0) {
      --im.skip_reuse;
      im.stale = true;
    }
  }
  *x = xk;
  return true;
}

}  // namespace mvtwin::forward
