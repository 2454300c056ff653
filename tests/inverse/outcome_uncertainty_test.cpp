#include "mvtwin/inverse/outcome_uncertainty.h"

#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "mvtwin/core/error.h"
#include "mvtwin/inverse/parameter_space.h"

namespace mvtwin::inverse {
namespace {

Eigen::MatrixXd random_covariance(int n, int rank, unsigned seed) {
  std::mt19937 gen(seed);
  std::normal_distribution<double> nd;
  Eigen::MatrixXd L(n, rank);
  for (Eigen::Index i = 0; i < L.size(); ++i) L.data()[i] = 0.1 * nd(gen);
  return L * L.transpose();
}

/// Outcomes of a linear model at every sigma point.
Eigen::MatrixXd at_points(const SigmaPoints& sp, const Eigen::MatrixXd& A,
                          const Eigen::VectorXd& b) {
  Eigen::MatrixXd m(static_cast<Eigen::Index>(sp.points.size()), A.rows());
  for (size_t i = 0; i < sp.points.size(); ++i)
    m.row(static_cast<Eigen::Index>(i)) = (A * sp.points[i] + b).transpose();
  return m;
}

TEST(OutcomeUncertainty, LinearOutcomesGetTheirExactStandardDeviation) {
  // For f(x) = A x + b the propagated variance is diag(A C A^T), whatever the correlations,
  // and also where the bounds force points the other way or shorten them.
  const int n = 3;
  const Eigen::MatrixXd C = random_covariance(n, n, 5);
  Eigen::MatrixXd A(2, n);
  A << 1.0, -2.0, 0.5, 3.0, 0.0, -1.0;
  const Eigen::VectorXd b = Eigen::Vector2d(4.0, -7.0);
  const Eigen::VectorXd lo = Eigen::VectorXd::Constant(n, -10.0);
  for (double room : {10.0, 0.05, 0.02}) {  // plenty; one SD does not fit one way; nor the other
    SCOPED_TRACE(room);
    const Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
    const Eigen::VectorXd hi = Eigen::VectorXd::Constant(n, room);
    const Eigen::VectorXd lo2 = room < 0.03 ? Eigen::VectorXd::Constant(n, -room) : lo;
    const SigmaPoints sp = sigma_points(x, C, lo2, hi);
    ASSERT_EQ(sp.points.size(), 3u);
    bool reflected = false;
    for (size_t i = 0; i < sp.points.size(); ++i) {
      EXPECT_TRUE((sp.points[i].array() <= hi.array() + 1e-12).all());
      EXPECT_TRUE((sp.points[i].array() >= lo2.array() - 1e-12).all());
      reflected = reflected || sp.scale[i] < 1.0;
    }
    // Near one bound only, a point goes the other way; between two near bounds their prior
    // shrinks the spread (checked below) and the points may then fit.
    if (room != 0.02) {
      EXPECT_EQ(reflected, room < 1.0) << "the bounds are felt only where they are near";
    }
    // The posterior with the bounds' prior, written out as the textbook has it (C is full
    // rank here): (C^-1 + diag(12 / (hi - lo)^2))^-1.
    const Eigen::VectorXd w = hi - lo2;
    const Eigen::MatrixXd Cb =
        (C.inverse() + Eigen::VectorXd(12.0 / w.array().square()).asDiagonal().toDenseMatrix())
            .inverse();
    EXPECT_LT((sp.covariance - Cb).norm(), 1e-10 * Cb.norm());
    const Eigen::VectorXd sd = propagated_sd(sp, A * x + b, at_points(sp, A, b));
    const Eigen::VectorXd expected = (A * Cb * A.transpose()).diagonal().cwiseSqrt();
    EXPECT_LT((sd - expected).norm(), 1e-10 * expected.norm()) << sd.transpose();
    // Far bounds leave the fit's covariance as it is (within 1 %).
    if (room > 1.0) {
      EXPECT_LT((expected - (A * C * A.transpose()).diagonal().cwiseSqrt()).norm(),
                0.01 * expected.norm());
    }
    // The difference of the two outcomes: its variance (a - b)^T C (a - b), not the sum of
    // theirs.
    const Eigen::MatrixXd P = at_points(sp, A, b);
    const Eigen::VectorXd ab = A.row(0) - A.row(1);
    EXPECT_NEAR(difference_sd(sp, b[0], P.col(0), b[1], P.col(1)), std::sqrt(ab.dot(Cb * ab)),
                1e-10);
  }
}

TEST(OutcomeUncertainty, DirectionsTheDataDoNotDetermineGetTheRangesSpread) {
  const Eigen::MatrixXd C = random_covariance(4, 2, 9);  // rank 2
  const Eigen::VectorXd x = Eigen::VectorXd::Constant(4, 1.0);
  const Eigen::VectorXd lo = Eigen::VectorXd::Constant(4, -5), hi = Eigen::VectorXd::Constant(4, 5);
  const SigmaPoints sp = sigma_points(x, C, lo, hi);
  EXPECT_EQ(sp.points.size(), 4u);
  // The posterior's precision is the fit's (the pseudo-inverse of C) plus the prior's, 12 / 10^2.
  const Eigen::MatrixXd precision =
      C.completeOrthogonalDecomposition().pseudoInverse() + Eigen::MatrixXd::Identity(4, 4) * 0.12;
  EXPECT_LT((sp.covariance * precision - Eigen::MatrixXd::Identity(4, 4)).norm(), 1e-8);
  // Along C's null space the data say nothing: exactly the range's variance, 100 / 12.
  const Eigen::MatrixXd null = C.fullPivLu().kernel();
  ASSERT_EQ(null.cols(), 2);
  const Eigen::VectorXd v = null.col(0).normalized();
  EXPECT_NEAR(v.dot(sp.covariance * v), 100.0 / 12.0, 1e-8);
  // Where the data see (C's range), the fit's spread is kept: the bounds are far.
  Eigen::MatrixXd A = Eigen::MatrixXd::Ones(1, 4);
  const Eigen::VectorXd sd = propagated_sd(sp, A * x, at_points(sp, A, Eigen::VectorXd::Zero(1)));
  EXPECT_NEAR(sd[0], std::sqrt((A * sp.covariance * A.transpose())(0, 0)), 1e-10);
  const Eigen::VectorXd seen = C * Eigen::VectorXd::Ones(4);
  EXPECT_NEAR(seen.dot(sp.covariance.ldlt().solve(seen)),
              seen.dot(C.completeOrthogonalDecomposition().solve(seen)),
              0.02 * seen.dot(C.completeOrthogonalDecomposition().solve(seen)));
  // Neither data nor bounds: left out (no points, zero spread).
  const Eigen::VectorXd inf = Eigen::VectorXd::Constant(4, INFINITY);
  const SigmaPoints open = sigma_points(x, C, -inf, inf);
  EXPECT_EQ(open.points.size(), 2u);
  const SigmaPoints none = sigma_points(x, Eigen::MatrixXd::Zero(4, 4), -inf, inf);
  EXPECT_TRUE(none.points.empty());
  EXPECT_EQ(propagated_sd(none, Eigen::VectorXd::Ones(2), Eigen::MatrixXd(0, 2)),
            Eigen::VectorXd::Zero(2));
}

TEST(OutcomeUncertainty, AParameterTheDataBarelySeeGetsItsRangesSpreadNotTheFits) {
  // As calibrated on cohort seed 2026's patient 6: a rest-length factor in [0.7, 1.6] with a
  // fitted SD of 50, beside a well-determined one (SD 0.003). Without the bounds' prior the
  // point along the first is 0.7 % of an SD long, and an outcome that jumps by 10 over any move
  // gets an SD of 10 / 0.007 = 1,400.
  Eigen::Matrix2d C;
  C << 2500.0, 0.005, 0.005, 9e-6;
  const Eigen::Vector2d x(1.26, 1.0), lo(0.7, 0.7), hi(1.6, 1.6);
  const SigmaPoints sp = sigma_points(x, C, lo, hi);
  ASSERT_EQ(sp.points.size(), 2u);
  const double range_var = 0.9 * 0.9 / 12.0;
  EXPECT_LT(sp.covariance(0, 0), range_var);
  EXPECT_GT(sp.covariance(0, 0), 0.99 * range_var) << "the data say nothing: the range's";
  EXPECT_NEAR(std::sqrt(sp.covariance(1, 1)), 0.003, 0.003 * 0.01) << "the data decide";
  for (size_t i = 0; i < sp.points.size(); ++i) {
    EXPECT_GE(std::abs(sp.scale[i]), 0.5) << "a step long enough for a secant";
    EXPECT_TRUE((sp.points[i].array() <= hi.array()).all() &&
                (sp.points[i].array() >= lo.array()).all());
  }
  Eigen::MatrixXd P(2, 1);
  for (int i = 0; i < 2; ++i) P(i, 0) = sp.points[static_cast<size_t>(i)][0] > x[0] ? 10.0 : 0.0;
  EXPECT_LE(propagated_sd(sp, Eigen::VectorXd::Zero(1), P)[0], 10.0 / 0.5 + 1e-9);
  // Bounds that are not a range (equal, reversed or infinite) add no prior.
  const Eigen::Vector2d inf = Eigen::Vector2d::Constant(INFINITY);
  EXPECT_LT((bounded_covariance(C, -inf, inf) - C).norm(), 1e-9 * C.norm());
  EXPECT_LT((bounded_covariance(C, hi, lo) - C).norm(), 1e-9 * C.norm());
  EXPECT_THROW(bounded_covariance(C, Eigen::VectorXd::Zero(3), hi), Error);
}

TEST(OutcomeUncertainty, APointWhoseSimulationFailsIsTriedAgainNearerTheCenter) {
  // A linear outcome whose "simulation" fails farther than 0.6 of its point's SD step along
  // direction 0: the point is moved half way in, simulated again, and the SD is the exact one.
  const Eigen::MatrixXd C = random_covariance(2, 2, 3);
  const Eigen::Vector2d x(0.5, -0.2), lo(-10, -10), hi(10, 10);
  SigmaPoints sp = sigma_points(x, C, lo, hi);
  ASSERT_EQ(sp.points.size(), 2u);
  const Eigen::MatrixXd A = Eigen::RowVector2d(2.0, -1.0);
  const Eigen::VectorXd b = Eigen::VectorXd::Constant(1, 3.0);
  Eigen::MatrixXd P(2, 1);
  std::vector<size_t> reruns;
  auto simulate = [&](size_t i, double fails_beyond) {
    const double reach = std::abs(sp.scale[i]);
    P(static_cast<Eigen::Index>(i), 0) =
        reach > fails_beyond ? std::nan("") : (A * sp.points[i] + b)(0);
  };
  for (double fails_beyond : {0.6, 0.1}) {  // once moved in it runs; it never runs
    SCOPED_TRACE(fails_beyond);
    sp = sigma_points(x, C, lo, hi);
    reruns.clear();
    for (size_t i = 0; i < 2; ++i) simulate(i, i == 0 ? fails_beyond : 1e9);
    const int moved = halve_failed_points(
        &sp, [&](size_t i) { return std::isnan(P(static_cast<Eigen::Index>(i), 0)); },
        [&](const std::vector<size_t>& is) {
          for (size_t i : is) {
            reruns.push_back(i);
            simulate(i, i == 0 ? fails_beyond : 1e9);
          }
        });
    const double sd = propagated_sd(sp, A * x + b, P)[0];
    if (fails_beyond > 0.5) {
      EXPECT_EQ(moved, 1);
      EXPECT_EQ(reruns, std::vector<size_t>({0}));
      EXPECT_DOUBLE_EQ(std::abs(sp.scale[0]), 0.5);
      EXPECT_NEAR((sp.points[0] - x).norm(),
                  0.5 * (sigma_points(x, C, lo, hi).points[0] - x).norm(), 1e-12);
      EXPECT_NEAR(sd, std::sqrt((A * sp.covariance * A.transpose())(0, 0)), 1e-10);
    } else {
      EXPECT_EQ(moved, 2) << "twice at most";
      EXPECT_EQ(reruns, std::vector<size_t>({0, 0}));
      EXPECT_DOUBLE_EQ(std::abs(sp.scale[0]), 0.25);
      EXPECT_TRUE(std::isnan(sd)) << "still failing: unknown, not zero";
    }
    EXPECT_DOUBLE_EQ(std::abs(sp.scale[1]), 1.0) << "a point that ran is left alone";
  }
}

TEST(OutcomeUncertainty, ANonlinearOutcomeIsLinearizedToFirstOrder) {
  // f = exp(x0) x1 at small spread: the first-order SD sqrt(g^T C g), within the secant's
  // second-order error.
  Eigen::Matrix2d C;
  C << 0.0004, 0.0001, 0.0001, 0.0009;
  const Eigen::Vector2d x(0.3, 2.0);
  const SigmaPoints sp = sigma_points(x, C, Eigen::Vector2d(-1, 0), Eigen::Vector2d(1, 4));
  Eigen::MatrixXd P(2, 1);
  for (int i = 0; i < 2; ++i)
    P(i, 0) = std::exp(sp.points[static_cast<size_t>(i)][0]) * sp.points[static_cast<size_t>(i)][1];
  Eigen::VectorXd c(1);
  c[0] = std::exp(x[0]) * x[1];
  const Eigen::Vector2d g(std::exp(x[0]) * x[1], std::exp(x[0]));
  const double expected = std::sqrt(g.dot(C * g));
  EXPECT_NEAR(propagated_sd(sp, c, P)[0], expected, 0.03 * expected);
  // A failed simulation (NaN) makes the SD unknown, not zero.
  P(1, 0) = std::nan("");
  EXPECT_TRUE(std::isnan(propagated_sd(sp, c, P)[0]));
}

TEST(OutcomeUncertainty, RefusesInconsistentInput) {
  EXPECT_THROW(sigma_points(Eigen::VectorXd::Zero(2), Eigen::MatrixXd::Identity(3, 3),
                            Eigen::VectorXd::Zero(2), Eigen::VectorXd::Ones(2)),
               Error);
  Eigen::MatrixXd bad = Eigen::MatrixXd::Identity(2, 2);
  bad(0, 1) = std::nan("");
  EXPECT_THROW(sigma_points(Eigen::VectorXd::Zero(2), bad, -Eigen::VectorXd::Ones(2),
                            Eigen::VectorXd::Ones(2)),
               Error);
  const SigmaPoints sp = sigma_points(Eigen::VectorXd::Zero(2), Eigen::MatrixXd::Identity(2, 2),
                                      -Eigen::VectorXd::Ones(2), Eigen::VectorXd::Ones(2));
  EXPECT_THROW(propagated_sd(sp, Eigen::VectorXd::Zero(1), Eigen::MatrixXd::Zero(1, 1)), Error);
}

TEST(OutcomeUncertainty, ACalibrationRecordsPosteriorFollowsItsParameterNames) {
  // A record listing its parameters in another order than the catalogue: the covariance is
  // permuted with them, and the fitted values come from the full set.
  const ParameterSpace space(
      "restlength_factor_posteromedial_marginal,restlength_factor_anterolateral_marginal",
      ValveParameters{});
  ASSERT_EQ(space.size(), 2);
  const std::string first = space.specs()[0].name, second = space.specs()[1].name;
  CalibrationRecord r;
  r.names = {second, first};
  r.parameters = space.apply(Eigen::Vector2d(1.1, 0.95));
  r.covariance.resize(2, 2);
  r.covariance << 0.04, 0.01, 0.01, 0.09;  // in the record's order: second, first
  r.sd = Eigen::Vector2d(0.2, std::nan(""));
  const CalibrationPosterior post = posterior_of(r);
  ASSERT_TRUE(post.usable) << post.why_not;
  EXPECT_NEAR(post.fitted[0], 1.1, 1e-12);
  EXPECT_NEAR(post.fitted[1], 0.95, 1e-12);
  EXPECT_DOUBLE_EQ(post.covariance(0, 0), 0.09);  // the catalogue's first is the record's second
  EXPECT_DOUBLE_EQ(post.covariance(1, 1), 0.04);
  EXPECT_DOUBLE_EQ(post.covariance(0, 1), 0.01);
  ASSERT_EQ(post.unidentified.size(), 1u);
  EXPECT_EQ(post.unidentified[0], first);
  const ValveParameters moved = post.apply(Eigen::Vector2d(1.2, 0.9));
  EXPECT_NEAR(space.values_of(moved)[0], 1.2, 1e-12);
  // Without a covariance there is nothing to propagate, and it says why.
  r.covariance.resize(0, 0);
  const CalibrationPosterior none = posterior_of(r);
  EXPECT_FALSE(none.usable);
  EXPECT_NE(none.why_not.find("covariance"), std::string::npos);
}

TEST(OutcomeUncertainty, ACalibrationsBoundedSdsAreTheRangesSpreadWhereTheDataBarelySee) {
  // The clip study's patient 6: a rest-length factor with an SD of 50 in [0.7, 1.6] beside a
  // well-determined one (0.01 in [0.5, 1.5]) and one the data do not see at all.
  CalibrationRecord r;
  r.names = {"a", "b", "c"};
  r.covariance = Eigen::Vector3d(50.0 * 50.0, 0.01 * 0.01, 0.0).asDiagonal();
  r.lower = Eigen::Vector3d(0.7, 0.5, 0.2);
  r.upper = Eigen::Vector3d(1.6, 1.5, 5.0);
  const Eigen::VectorXd sd = bounded_sd(r);
  ASSERT_EQ(sd.size(), 3);
  // (1 / 50^2 + 12 / 0.9^2)^(-1/2): the range's 0.26, a little less.
  EXPECT_NEAR(sd[0], 1.0 / std::sqrt(1.0 / 2500.0 + 12.0 / 0.81), 1e-9);
  EXPECT_LT(sd[0], 0.9 / std::sqrt(12.0));
  EXPECT_NEAR(sd[1], 0.01, 0.01 * 1e-3) << "the data's SD, kept";
  EXPECT_NEAR(sd[2], 4.8 / std::sqrt(12.0), 1e-9) << "the range's spread";
  // Neither the data nor bounds limit it: unknown.
  r.lower[2] = -std::numeric_limits<double>::infinity();
  EXPECT_TRUE(std::isnan(bounded_sd(r)[2]));
  EXPECT_NEAR(bounded_sd(r)[1], 0.01, 1e-5);
  // No covariance (or bounds of another size): nothing to say.
  r.lower.resize(2);
  EXPECT_TRUE(bounded_sd(r).array().isNaN().all());
  r.covariance.resize(0, 0);
  EXPECT_TRUE(bounded_sd(r).array().isNaN().all());
}

}  // namespace
}  // namespace mvtwin::inverse
