#include "mvtwin/forward/step_solver.h"

#include <limits>

#include <gtest/gtest.h>
#include <Eigen/SparseCholesky>

#include "mvtwin/core/error.h"
#include "mvtwin/core/rng.h"

namespace mvtwin::forward {
namespace {

// A 2D Laplacian plus a diagonal shift: symmetric positive definite, like M + h^2 K.
Eigen::SparseMatrix<double> laplacian(int n, double shift) {
  std::vector<Eigen::Triplet<double>> t;
  auto id = [n](int i, int j) { return i * n + j; };
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      t.emplace_back(id(i, j), id(i, j), 4.0 + shift);
      if (i > 0) t.emplace_back(id(i, j), id(i - 1, j), -1.0);
      if (i + 1 < n) t.emplace_back(id(i, j), id(i + 1, j), -1.0);
      if (j > 0) t.emplace_back(id(i, j), id(i, j - 1), -1.0);
      if (j + 1 < n) t.emplace_back(id(i, j), id(i, j + 1), -1.0);
    }
  }
  Eigen::SparseMatrix<double> A(n * n, n * n);
  A.setFromTriplets(t.begin(), t.end());
  return A;
}

class StepSolverTest : public ::testing::TestWithParam<LinearSolver> {};

TEST_P(StepSolverTest, SolvesASequenceOfSystems) {
  StepSolverOptions o;
  o.kind = GetParam();
  o.pcg_tolerance = 1e-8;
  o.refactor_iterations = 8;
  StepSolver s(o);
  Rng rng(3);
  Eigen::VectorXd b(900);
  for (int i = 0; i < 900; ++i) b[i] = rng.normal();
  for (double shift : {0.1, 0.12, 0.2, 1.0}) {
    const Eigen::SparseMatrix<double> A = laplacian(30, shift);
    Eigen::VectorXd x;
    std::string why;
    ASSERT_TRUE(s.solve(A, b, &x, &why)) << why;
    EXPECT_LT((A * x - b).norm(), 1e-7 * b.norm()) << name(GetParam());
  }
  EXPECT_EQ(s.stats().analyses, 1);  // same pattern throughout
  if (GetParam() == LinearSolver::kReusedFactorPcg) {
    EXPECT_LT(s.stats().factorizations, 4);  // nearby matrices reuse the factor
    EXPECT_GT(s.stats().pcg_iterations, 0);
  } else {
    EXPECT_EQ(s.stats().factorizations, 4);
  }
}

TEST_P(StepSolverTest, IndefiniteMatrixFailsWithAReason) {
  StepSolverOptions o;
  o.kind = GetParam();
  StepSolver s(o);
  const Eigen::SparseMatrix<double> A = laplacian(10, -10.0);
  Eigen::VectorXd x, b = Eigen::VectorXd::Ones(100);
  std::string why;
  const bool ok = s.solve(A, b, &x, &why);
  if (GetParam() == LinearSolver::kEigenLdlt) {
    // LDL^T factorizes indefinite matrices; the answer must still solve the system.
    if (ok) {
      EXPECT_LT((A * x - b).norm(), 1e-8 * b.norm());
    }
  } else {
    EXPECT_FALSE(ok);
    EXPECT_NE(why.find("not positive definite"), std::string::npos);
  }
}

INSTANTIATE_TEST_SUITE_P(All, StepSolverTest,
                         ::testing::Values(LinearSolver::kCholmodSupernodal,
                                           LinearSolver::kCholmodSimplicial,
                                           LinearSolver::kEigenLdlt,
                                           LinearSolver::kReusedFactorPcg),
                         [](const auto& param_info) {
                           std::string n = name(param_info.param);
                           for (char& c : n)
                             if (c == '-') c = '_';
                           return n;
                         });

// The single-precision preconditioner: a supernodal factorization applied in float still gives
// solutions to the tolerance (CG on the double operator makes up for the rounding, in a few
// iterations), equal to the double-precision factor's to that tolerance.
TEST(StepSolver, SinglePrecisionPreconditionerReachesTheTolerance) {
  Rng rng(8);
  Eigen::VectorXd b(2500);
  for (int i = 0; i < b.size(); ++i) b[i] = rng.normal();
  const Eigen::SparseMatrix<double> A = laplacian(50, 0.05);
  Eigen::VectorXd xs, xd;
  std::string why;
  StepSolverOptions o;
  o.kind = LinearSolver::kCholmodSupernodal;
  o.pcg_tolerance = 1e-10;
  o.single_precision_preconditioner = true;
  StepSolver single(o);
  ASSERT_TRUE(single.solve(A, b, &xs, &why)) << why;
  o.single_precision_preconditioner = false;
  StepSolver dbl(o);
  ASSERT_TRUE(dbl.solve(A, b, &xd, &why)) << why;
  EXPECT_LT((A * xs - b).norm(), 1e-10 * b.norm());
  EXPECT_LT((xs - xd).norm(), 1e-8 * xd.norm());
  EXPECT_GT(single.stats().pcg_iterations, 0);  // float rounding needs a few iterations ...
  EXPECT_LT(single.stats().pcg_iterations, 8);  // ... but only a few
  EXPECT_EQ(dbl.stats().pcg_iterations, 0);     // the double factor solves it outright
}

// The single-precision preconditioner factorized in single precision (sgemm, spotrf) instead of
// rounded from a double factorization: a few more CG iterations at most, the same solution to the
// tolerance, no fallback on a well-conditioned matrix.
TEST(StepSolver, SinglePrecisionFactorizationReachesTheTolerance) {
  Rng rng(9);
  Eigen::VectorXd b(2500);
  for (int i = 0; i < b.size(); ++i) b[i] = rng.normal();
  const Eigen::SparseMatrix<double> A = laplacian(50, 0.05);
  StepSolverOptions o;
  o.kind = LinearSolver::kCholmodSupernodal;
  o.pcg_tolerance = 1e-10;
  Eigen::VectorXd x[2];
  int iterations[2];
  for (bool single : {false, true}) {
    o.single_precision_factorization = single;
    StepSolver s(o);
    std::string why;
    ASSERT_TRUE(s.solve(A, b, &x[single], &why)) << why;
    EXPECT_LT((A * x[single] - b).norm(), 1e-10 * b.norm());
    EXPECT_EQ(s.stats().double_fallbacks, 0);
    iterations[single] = s.stats().pcg_iterations;
  }
  EXPECT_LT((x[1] - x[0]).norm(), 1e-8 * x[0].norm());
  EXPECT_LE(iterations[1], iterations[0] + 2);
  EXPECT_NE(x[0], x[1]);  // a different factor: not the rounded double one
}

// A matrix positive definite in double but not in single precision (2 x 2 blocks [1, 1 - d;
// 1 - d, 1] with d = 2e-8: in float 1 - d rounds to 1 and the block is singular): the
// single-precision factorization fails, is redone and applied in double (a float preconditioner
// of such a matrix would not reach the tolerance) and counted, and the solve reaches the
// tolerance.
TEST(StepSolver, SinglePrecisionFactorizationFallsBackToDouble) {
  const int blocks = 200;
  const double d = 2e-8;
  std::vector<Eigen::Triplet<double>> t;
  for (int k = 0; k < blocks; ++k) {
    t.emplace_back(2 * k, 2 * k, 1.0);
    t.emplace_back(2 * k + 1, 2 * k + 1, 1.0);
    t.emplace_back(2 * k, 2 * k + 1, 1.0 - d);
    t.emplace_back(2 * k + 1, 2 * k, 1.0 - d);
  }
  Eigen::SparseMatrix<double> A(2 * blocks, 2 * blocks);
  A.setFromTriplets(t.begin(), t.end());
  Rng rng(4);
  Eigen::VectorXd b(2 * blocks);
  for (int i = 0; i < b.size(); ++i) b[i] = rng.normal();
  StepSolverOptions o;
  o.kind = LinearSolver::kCholmodSupernodal;
  o.pcg_tolerance = 1e-6;
  StepSolver s(o);
  Eigen::VectorXd x;
  std::string why;
  ASSERT_TRUE(s.solve(A, b, &x, &why)) << why;
  EXPECT_LT((A * x - b).norm(), 1e-6 * b.norm());
  EXPECT_EQ(s.stats().double_fallbacks, 1);
  // The double factor applied in double solves it outright; rounded to float it would not.
  EXPECT_EQ(s.stats().pcg_iterations, 0);
}

// The single-precision substitutions run in two parts (subtrees of the elimination tree) and
// the rest; with threads = 2 at once. The solution is the same to the last bit either way, and
// the split factor is still the factor: a few CG iterations to 1e-10, as in one piece.
TEST(StepSolver, TwoThreadsSolveBitForBitAsOne) {
  Rng rng(21);
  const Eigen::SparseMatrix<double> A = laplacian(70, 0.02);
  Eigen::VectorXd b(A.rows());
  for (int i = 0; i < b.size(); ++i) b[i] = rng.normal();
  StepSolverOptions o;
  o.kind = LinearSolver::kCholmodSupernodal;
  o.pcg_tolerance = 1e-10;
  Eigen::VectorXd x[2];
  for (int threads : {1, 2}) {
    StepSolver s(o);
    s.set_threads(threads);
    std::string why;
    ASSERT_TRUE(s.solve(A, b, &x[threads - 1], &why)) << why;
    EXPECT_LT((A * x[threads - 1] - b).norm(), 1e-10 * b.norm());
    EXPECT_LT(s.stats().pcg_iterations, 8) << threads << " threads";
  }
  EXPECT_EQ(x[0], x[1]);
}

// A second solver on the same pattern reuses the first one's ordering (a calibration's many
// simulations of one model) and gets the factor a fresh analysis gives: the same solution to the
// last bit. A pattern used nowhere else in this file (37 x 37), so that what ran before in the
// process cannot have stored it.
TEST(StepSolver, ASecondSolverReusesTheOrderingAndSolvesBitForBit) {
  Rng rng(12);
  Eigen::VectorXd b(37 * 37);
  for (int i = 0; i < b.size(); ++i) b[i] = rng.normal();
  const Eigen::SparseMatrix<double> A = laplacian(37, 0.3);
  std::string why;
  Eigen::VectorXd x1, x2, x3;
  StepSolver first{StepSolverOptions{}};
  ASSERT_TRUE(first.solve(A, b, &x1, &why)) << why;
  EXPECT_EQ(first.stats().analyses, 1);
  EXPECT_EQ(first.stats().orderings_reused, 0);
  StepSolver second{StepSolverOptions{}};
  ASSERT_TRUE(second.solve(A, b, &x2, &why)) << why;
  EXPECT_EQ(second.stats().analyses, 1);
  EXPECT_EQ(second.stats().orderings_reused, 1);
  EXPECT_EQ(x1, x2);  // bit for bit
  // Another pattern is analysed afresh.
  const Eigen::SparseMatrix<double> B = laplacian(36, 0.3);
  StepSolver other{StepSolverOptions{}};
  ASSERT_TRUE(other.solve(B, b.head(36 * 36), &x3, &why)) << why;
  EXPECT_EQ(other.stats().orderings_reused, 0);
  EXPECT_LT((B * x3 - b.head(36 * 36)).norm(), 0.1 * b.head(36 * 36).norm());
}

// A vector of zeros but for one NaN.
Eigen::VectorXd bad_nan(Eigen::Index n) {
  Eigen::VectorXd v = Eigen::VectorXd::Zero(n);
  v[n / 2] = std::numeric_limits<double>::quiet_NaN();
  return v;
}

// A System over a full symmetric matrix with optional guesses.
StepSolver::System system_of(const Eigen::SparseMatrix<double>& A,
                             const Eigen::SparseMatrix<double>& lower,
                             const std::vector<Eigen::VectorXd>* guesses) {
  StepSolver::System s;
  s.multiply = [&A](const Eigen::VectorXd& v, Eigen::VectorXd* y) { *y = A * v; };
  s.lower = [&lower]() -> const Eigen::SparseMatrix<double>& { return lower; };
  s.guesses = guesses;
  return s;
}

// Warm start: a guess that already solves the system is the answer, with no factorization and
// no preconditioner application; one that does not still gives a solution to the tolerance.
// Systems that change too fast for a reused factor (settling's long steps): a factor that failed
// once (PCG ran to its cap and fell back to a new factorization) is not tried on the next system;
// that one is factorized at once. Before, every other solve tried the old factor, failed and fell
// back (7 fallbacks in 8 solves here, and their PCG iterations wasted); now after each failure
// the next 1, 2, 4, ... solves factorize at once (3).
TEST(StepSolver, AFactorThatFailedIsNotTriedOnTheNextSystem) {
  StepSolverOptions o;
  o.kind = LinearSolver::kReusedFactorPcg;
  o.pcg_tolerance = 1e-10;
  o.pcg_max_iterations = 3;
  StepSolver s(o);
  Rng rng(5);
  Eigen::VectorXd b(400);
  for (int i = 0; i < b.size(); ++i) b[i] = rng.normal();
  for (double shift : {0.01, 10.0, 0.01, 10.0, 0.01, 10.0, 0.01, 10.0}) {
    const Eigen::SparseMatrix<double> A = laplacian(20, shift);
    Eigen::VectorXd x;
    std::string why;
    ASSERT_TRUE(s.solve(A, b, &x, &why)) << why;
    EXPECT_LT((A * x - b).norm(), 1e-9 * b.norm()) << shift;
  }
  EXPECT_EQ(s.stats().factorizations, 8);
  EXPECT_EQ(s.stats().pcg_fallbacks, 3);
}

TEST(StepSolver, AGuessThatSolvesTheSystemNeedsNoFactorization) {
  Rng rng(31);
  const Eigen::SparseMatrix<double> A = laplacian(20, 0.1);
  const Eigen::SparseMatrix<double> lower = A.triangularView<Eigen::Lower>();
  Eigen::VectorXd b(A.rows());
  for (int i = 0; i < b.size(); ++i) b[i] = rng.normal();
  const Eigen::VectorXd exact = Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>(A).solve(b);
  StepSolverOptions o;
  o.warm_start = true;
  o.pcg_tolerance = 1e-6;
  std::string why;
  {
    // Twice the solution: the best multiple of it is the solution itself.
    const std::vector<Eigen::VectorXd> guesses{2.0 * exact};
    StepSolver s(o);
    Eigen::VectorXd x;
    ASSERT_TRUE(s.solve(system_of(A, lower, &guesses), b, &x, &why)) << why;
    EXPECT_LT((A * x - b).norm(), 1e-6 * b.norm());
    EXPECT_EQ(s.stats().warm_accepted, 1);
    EXPECT_EQ(s.stats().factorizations, 0);
    EXPECT_EQ(s.stats().applications, 0);
  }
  {
    // The solution beside a vector of zeros and a non-finite one: those two are ignored, so the
    // solution still answers alone.
    const std::vector<Eigen::VectorXd> with_bad{Eigen::VectorXd::Zero(b.size()), 2.0 * exact,
                                                bad_nan(b.size())};
    StepSolver s(o);
    Eigen::VectorXd x;
    ASSERT_TRUE(s.solve(system_of(A, lower, &with_bad), b, &x, &why)) << why;
    EXPECT_LT((A * x - b).norm(), 1e-6 * b.norm());
    EXPECT_EQ(s.stats().warm_accepted, 1);
    EXPECT_EQ(s.stats().factorizations, 0);
  }
  {
    // Noise, a vector of zeros and a non-finite one: ignored or outweighed, the answer meets
    // the tolerance all the same.
    Eigen::VectorXd noise(b.size()), nan = Eigen::VectorXd::Zero(b.size());
    for (int i = 0; i < b.size(); ++i) noise[i] = rng.normal();
    nan[3] = std::numeric_limits<double>::quiet_NaN();
    const std::vector<Eigen::VectorXd> guesses{noise, Eigen::VectorXd::Zero(b.size()), nan};
    StepSolver s(o);
    Eigen::VectorXd x;
    ASSERT_TRUE(s.solve(system_of(A, lower, &guesses), b, &x, &why)) << why;
    EXPECT_LT((A * x - b).norm(), 1e-6 * b.norm());
    EXPECT_EQ(s.stats().warm_accepted, 0);
    EXPECT_EQ(s.stats().factorizations, 1);
  }
}

// A sequence of slowly changing systems, as the steps of a closure: with the last two solutions
// as guesses, the reused factor needs fewer preconditioner applications for the same tolerance,
// and every solution still meets it.
TEST(StepSolver, EarlierSolutionsAsGuessesSaveApplications) {
  Rng rng(32);
  Eigen::VectorXd b0(30 * 30), db(30 * 30);
  for (int i = 0; i < b0.size(); ++i) {
    b0[i] = rng.normal();
    db[i] = rng.normal();
  }
  int applications[2] = {0, 0};
  for (bool warm : {false, true}) {
    StepSolverOptions o;
    o.warm_start = warm;
    o.pcg_tolerance = 0.01;
    StepSolver s(o);
    std::vector<Eigen::VectorXd> last;
    for (int k = 0; k < 40; ++k) {
      const Eigen::SparseMatrix<double> A = laplacian(30, 0.1 + 0.01 * k);
      const Eigen::SparseMatrix<double> lower = A.triangularView<Eigen::Lower>();
      const Eigen::VectorXd b = b0 + 0.02 * k * db;
      Eigen::VectorXd x;
      std::string why;
      ASSERT_TRUE(s.solve(system_of(A, lower, warm ? &last : nullptr), b, &x, &why)) << why;
      EXPECT_LE((A * x - b).norm(), 0.01 * b.norm() * (1 + 1e-12)) << k;
      last.insert(last.begin(), x);
      if (last.size() > 2) last.pop_back();
    }
    applications[warm] = s.stats().applications;
    if (!warm) {
      EXPECT_EQ(s.stats().warm_starts, 0);
    }
  }
  EXPECT_LT(applications[1], applications[0] * 3 / 4)
      << applications[1] << " with guesses, " << applications[0] << " without";
}

TEST(StepSolver, InvalidOptionsAreRefusedNamingTheField) {
  StepSolverOptions o;
  std::string why;
  EXPECT_TRUE(o.is_valid(&why)) << why;  // the defaults are valid
  o.pcg_tolerance = 0.0;
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find("pcg_tolerance"), std::string::npos) << why;
  EXPECT_THROW(StepSolver{o}, Error);
  o = StepSolverOptions{};
  o.refactor_iterations = 0;
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find("refactor_iterations"), std::string::npos) << why;
}

TEST(StepSolver, NamesRoundTrip) {
  for (LinearSolver k : {LinearSolver::kCholmodSupernodal, LinearSolver::kCholmodSimplicial,
                         LinearSolver::kEigenLdlt, LinearSolver::kReusedFactorPcg}) {
    LinearSolver back;
    ASSERT_TRUE(parse_linear_solver(name(k), &back));
    EXPECT_EQ(back, k);
  }
  LinearSolver dummy;
  EXPECT_FALSE(parse_linear_solver("gauss", &dummy));
}

}  // namespace
}  // namespace mvtwin::forward
