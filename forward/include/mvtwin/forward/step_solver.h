#pragma once
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace mvtwin::forward {

/// How the linear system of each implicit step is solved.
enum class LinearSolver {
  kCholmodSupernodal,  ///< CHOLMOD supernodal Cholesky, every system factorized
  kCholmodSimplicial,  ///< CHOLMOD simplicial (up-looking) Cholesky, every system factorized
  kEigenLdlt,          ///< Eigen's SimplicialLDLT (AMD), every system factorized
  kReusedFactorPcg,    ///< conjugate gradients preconditioned by an earlier (supernodal)
                       ///< factorization, refactorized when CG needs too many iterations
};

const char* name(LinearSolver s);
/// Parses a solver name (as printed by name()); false if unknown.
bool parse_linear_solver(const std::string& text, LinearSolver* out);

/// Options of the step solver, with the closure simulation's defaults: conjugate gradients to a
/// loose relative tolerance, preconditioned by a factorization reused over steps (measured in
/// `mvtwin bench solvers`: the cheapest at the error the closure tolerates).
struct StepSolverOptions {
  LinearSolver kind = LinearSolver::kReusedFactorPcg;
  /// Relative residual CG solves to (every kind: the direct kinds then iterate only over the
  /// terms their factorization leaves out).
  double pcg_tolerance = 0.1;
  int pcg_max_iterations = 25;  ///< beyond this, refactorize and solve again
  /// A solve this long makes the next one refactorize (one factorization of the paper's grid
  /// costs about 14 CG iterations; 5 was measured faster, not yet made the default).
  int refactor_iterations = 3;
  /// Supernodal kinds: apply the factorization as the preconditioner from a single-precision
  /// copy (half the memory traffic of the memory-bound triangular solves; CG on the exact
  /// double-precision operator still reaches any tolerance).
  bool single_precision_preconditioner = true;
  /// With the single-precision preconditioner: factorize in single precision too (sgemm,
  /// spotrf), half the traffic and twice the SIMD width of the double factorization that was
  /// rounded to single afterwards. A matrix that is not positive definite in single precision
  /// is factorized and applied in double instead (Stats::double_fallbacks).
  bool single_precision_factorization = true;
  /// Use System::rotate when the system has one (rotated preconditioner, see System).
  bool rotated_preconditioner = true;
  /// Use the system's guesses (System::guesses): with earlier steps' updates, a step whose
  /// update is close to a combination of them needs fewer preconditioner applications, or none.
  /// Off by default: at the paper's grid it saves a third of the applications and a fifth of
  /// the factorizations but, with its extra matrix-free products, no measurable wall time on one
  /// thread, and it moves the closure onto another path, from which settling creeps longer
  /// (docs/forward-status.md, warm-started solves).
  bool warm_start = false;

  bool is_valid(std::string* error) const;
};

/// Solves the symmetric positive definite systems of a time integration, one after another. The
/// symbolic analysis is reused while the sparsity pattern stays the same.
///
/// Every kind solves the exact operator (System::multiply, which may hold terms the factorized
/// lower triangle leaves out, such as contact couplings) by conjugate gradients to the relative
/// tolerance pcg_tolerance, preconditioned by a Cholesky factorization of System::lower. The
/// direct kinds factorize every system (CG then only accounts for the terms left out: zero
/// iterations without contact). kReusedFactorPcg keeps the last factorization while CG reaches
/// the tolerance within pcg_max_iterations (else it factorizes and iterates again), and
/// factorizes the next system once a solve needed refactor_iterations or more.
/// Everything depends on iteration counts only, never on timings: same input, same output.
///
/// CHOLMOD's own OpenMP threads are switched off: candidate simulations run in parallel one per
/// core, and on two cores its threads only contend (measured: 2.2x slower factorizations).
class StepSolver {
 public:
  struct Stats {
    int analyses = 0, factorizations = 0, solves = 0, pcg_iterations = 0, pcg_fallbacks = 0;
    int applications = 0;   ///< preconditioner (factor) applications
    int warm_starts = 0;    ///< solves given usable guesses (System::guesses)
    int warm_accepted = 0;  ///< of those, solves the guesses answered alone (no application)
    int unconverged = 0;    ///< solves that kept CG's last iterate after a fresh factorization
    /// Single-precision factorizations that failed (not positive definite in single precision)
    /// and were done again in double.
    int double_fallbacks = 0;
    double factorize_s = 0, apply_s = 0;  ///< time in factorizations and in factor solves
    double analyze_s = 0;  ///< part of factorize_s spent in symbolic analyses (orderings)
    /// Analyses that reused the ordering of an earlier solver in the process (same pattern).
    int orderings_reused = 0;
  };
  /// One system: y = A x, and A's lower triangle (column major) on a fixed pattern, asked for
  /// only when a factorization is due.
  struct System {
    std::function<void(const Eigen::VectorXd& x, Eigen::VectorXd* y)> multiply;
    std::function<const Eigen::SparseMatrix<double>&()> lower;
    /// Optional orthogonal change of basis Q (transpose = false) or Q^T (true), applied in
    /// place: the preconditioner becomes Q F^-1 Q^T, with F the last factorization. For a
    /// co-rotational solid, Q rotates each node by how its neighbourhood has rotated since the
    /// factorization, so that the stale factor stays a good preconditioner under large
    /// rotations.
    std::function<void(Eigen::VectorXd* v, bool transpose)> rotate;
    /// Optional guesses of the solution (earlier systems' solutions, scaled to this one). With
    /// warm_start, their best combination in A's energy is the answer when it meets the
    /// tolerance; else CG starts from the best combination of them and the preconditioned b.
    const std::vector<Eigen::VectorXd>* guesses = nullptr;
  };

  /// Throws mvtwin::Error for invalid options.
  explicit StepSolver(const StepSolverOptions& options);
  ~StepSolver();
  StepSolver(const StepSolver&) = delete;
  StepSolver& operator=(const StepSolver&) = delete;

  /// x = A^-1 b. False with a reason (not positive definite, non-finite) on failure.
  bool solve(const System& A, const Eigen::VectorXd& b, Eigen::VectorXd* x, std::string* why);
  /// x = A^-1 b for a nonsymmetric A (System::multiply; System::lower is the lower triangle of
  /// a symmetric positive definite approximation of it): flexible GMRES, restarted every
  /// pcg_max_iterations, right-preconditioned by the factorization of the approximation, kept
  /// over solves and redone under the same rules as solve()'s (refactor_iterations). False
  /// with a reason when the approximation is not positive definite or the result not finite;
  /// a solve that stops above the tolerance after two restarts keeps its last iterate (counted
  /// as unconverged).
  bool solve_nonsymmetric(const System& A, const Eigen::VectorXd& b, Eigen::VectorXd* x,
                          std::string* why);
  /// The same for a full (both triangles) symmetric matrix.
  bool solve(const Eigen::SparseMatrix<double>& A, const Eigen::VectorXd& b, Eigen::VectorXd* x,
             std::string* why);
  const Stats& stats() const { return stats_; }
  /// Changes the relative tolerance of the next solves (a Newton method's forcing term).
  void set_tolerance(double pcg_tolerance) { opt_.pcg_tolerance = pcg_tolerance; }
  /// Threads of a factorization and a preconditioner application (1 or 2; results do not
  /// depend on it): with the single-precision preconditioner, the supernodal factorization and
  /// substitutions run in two parts at once with 2.
  void set_threads(int threads);

 private:
  bool factorize(const System& A, std::string* why);
  /// Counts a solve and answers a right-hand side that needs no iteration (*done): false for a
  /// non-finite b (with *why), x = 0 for b = 0.
  bool begin_solve(const Eigen::VectorXd& b, Eigen::VectorXd* x, std::string* why, bool* done);
  /// One Krylov iteration to the tolerance: the iterate and the iterations it took; converged?
  using Iteration = std::function<bool(Eigen::VectorXd* x, int* iterations)>;
  /// Runs it, again after a fresh factorization when it fails with a reused one, and marks the
  /// factorization stale when it took refactor_iterations or more.
  bool iterate(const System& A, const Iteration& run, bool* fresh, Eigen::VectorXd* x,
               std::string* why);
  struct Impl;
  std::unique_ptr<Impl> impl_;
  StepSolverOptions opt_;
  Stats stats_;
};

}  // namespace mvtwin::forward
