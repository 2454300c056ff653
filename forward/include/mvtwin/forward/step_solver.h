#pragma once
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
  kReusedFactorPcg,    ///< conjugate gradients preconditioned by an earlier factorization,
                       ///< refactorized when CG needs too many iterations
};

const char* name(LinearSolver s);
/// Parses a solver name (as printed by name()); false if unknown.
bool parse_linear_solver(const std::string& text, LinearSolver* out);

/// Solves the symmetric positive definite systems of a time integration, one after another. The
/// symbolic analysis is reused while the sparsity pattern stays the same (contact pairs change
/// it; then the pattern is analysed again).
class StepSolver {
 public:
  struct Options {
    LinearSolver kind = LinearSolver::kCholmodSupernodal;
    double pcg_tolerance = 1e-8;  ///< relative residual for kReusedFactorPcg
    int pcg_max_iterations = 25;  ///< beyond this, refactorize and solve directly
  };
  struct Stats {
    int analyses = 0, factorizations = 0, solves = 0, pcg_iterations = 0, pcg_fallbacks = 0;
  };

  explicit StepSolver(const Options& options);
  ~StepSolver();
  StepSolver(const StepSolver&) = delete;
  StepSolver& operator=(const StepSolver&) = delete;

  /// x = A^-1 b. False with a reason (not positive definite, non-finite) on failure.
  bool solve(const Eigen::SparseMatrix<double>& A, const Eigen::VectorXd& b, Eigen::VectorXd* x,
             std::string* why);
  const Stats& stats() const { return stats_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  Options opt_;
  Stats stats_;
};

}  // namespace mvtwin::forward
