#include "mvtwin/forward/step_solver.h"

#include <cmath>
#include <cstring>

#include <Eigen/CholmodSupport>
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

/// A direct factorization whose symbolic analysis is redone only when the pattern changes.
class Factor {
 public:
  virtual ~Factor() = default;
  bool factorize(const Eigen::SparseMatrix<double>& A, StepSolver::Stats* st) {
    const bool same = A.rows() == rows_ && A.nonZeros() == static_cast<Eigen::Index>(inner_.size()) &&
                      std::memcmp(A.outerIndexPtr(), outer_.data(), outer_.size() * sizeof(int)) == 0 &&
                      std::memcmp(A.innerIndexPtr(), inner_.data(), inner_.size() * sizeof(int)) == 0;
    if (!same) {
      rows_ = A.rows();
      outer_.assign(A.outerIndexPtr(), A.outerIndexPtr() + A.outerSize() + 1);
      inner_.assign(A.innerIndexPtr(), A.innerIndexPtr() + A.nonZeros());
      analyze(A);
      ++st->analyses;
    }
    ++st->factorizations;
    return numeric(A);
  }
  virtual Eigen::VectorXd apply(const Eigen::VectorXd& b) const = 0;

 protected:
  virtual void analyze(const Eigen::SparseMatrix<double>& A) = 0;
  virtual bool numeric(const Eigen::SparseMatrix<double>& A) = 0;

 private:
  Eigen::Index rows_ = -1;
  std::vector<int> outer_, inner_;
};

template <typename Solver>
class FactorOf : public Factor {
 public:
  Eigen::VectorXd apply(const Eigen::VectorXd& b) const override { return s_.solve(b); }

 protected:
  void analyze(const Eigen::SparseMatrix<double>& A) override {
    if constexpr (requires { s_.cholmod(); }) {
      // AMD and METIS both tried, the ordering with less fill kept (METIS: ~20 % fewer flops
      // on the valve). The pattern is fixed over a run, so this is paid once.
      s_.cholmod().nmethods = 2;
      s_.cholmod().method[0].ordering = CHOLMOD_AMD;
      s_.cholmod().method[1].ordering = CHOLMOD_METIS;
    }
    s_.analyzePattern(A);
  }
  bool numeric(const Eigen::SparseMatrix<double>& A) override {
    s_.factorize(A);
    return s_.info() == Eigen::Success;
  }

 public:
  Solver s_;
};

}  // namespace

struct StepSolver::Impl {
  std::unique_ptr<Factor> factor;
  bool have_factor = false;
};

StepSolver::StepSolver(const Options& o) : impl_(std::make_unique<Impl>()), opt_(o) {
  switch (o.kind) {
    case LinearSolver::kCholmodSimplicial: {
      auto f = std::make_unique<FactorOf<Eigen::CholmodSimplicialLLT<Eigen::SparseMatrix<double>>>>();
      impl_->factor = std::move(f);
      break;
    }
    case LinearSolver::kEigenLdlt:
      impl_->factor = std::make_unique<FactorOf<Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>>>();
      break;
    case LinearSolver::kCholmodSupernodal:
    case LinearSolver::kReusedFactorPcg: {
      auto f = std::make_unique<FactorOf<Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>>>>();
      impl_->factor = std::move(f);
      break;
    }
  }
}

StepSolver::~StepSolver() = default;

bool StepSolver::solve(const Eigen::SparseMatrix<double>& A, const Eigen::VectorXd& b,
                       Eigen::VectorXd* x, std::string* why) {
  ++stats_.solves;
  auto direct = [&]() -> bool {
    if (!impl_->factor->factorize(A, &stats_)) {
      impl_->have_factor = false;
      *why = "linear solver failed (matrix not positive definite)";
      return false;
    }
    impl_->have_factor = true;
    *x = impl_->factor->apply(b);
    if (!x->allFinite()) {
      *why = "linear solver returned non-finite values";
      return false;
    }
    return true;
  };
  if (opt_.kind != LinearSolver::kReusedFactorPcg || !impl_->have_factor) return direct();

  // Preconditioned conjugate gradients with the previous factorization as preconditioner.
  const double bnorm = b.norm();
  if (!(bnorm > 0)) {
    *x = Eigen::VectorXd::Zero(b.size());
    return true;
  }
  Eigen::VectorXd xk = impl_->factor->apply(b);
  Eigen::VectorXd r = b - A * xk;
  Eigen::VectorXd z = impl_->factor->apply(r);
  Eigen::VectorXd p = z;
  double rz = r.dot(z);
  for (int it = 0; it < opt_.pcg_max_iterations; ++it) {
    if (r.norm() <= opt_.pcg_tolerance * bnorm) {
      *x = xk;
      return x->allFinite();
    }
    ++stats_.pcg_iterations;
    const Eigen::VectorXd Ap = A * p;
    const double pAp = p.dot(Ap);
    if (!(pAp > 0)) break;
    const double alpha = rz / pAp;
    xk += alpha * p;
    r -= alpha * Ap;
    z = impl_->factor->apply(r);
    const double rz_new = r.dot(z);
    p = z + (rz_new / rz) * p;
    rz = rz_new;
  }
  if (r.norm() <= opt_.pcg_tolerance * bnorm) {
    *x = xk;
    return x->allFinite();
  }
  ++stats_.pcg_fallbacks;
  return direct();
}

}  // namespace mvtwin::forward
