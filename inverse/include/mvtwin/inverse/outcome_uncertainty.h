#pragma once
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/calibration_file.h"
#include "mvtwin/core/valve_parameters.h"

namespace mvtwin::inverse {

/// Points at which to simulate an outcome so that its spread under a calibration's posterior
/// can be read off (docs/clip-devices.md, "How sure the answer is"). For each direction the
/// data determine (eigenvector v_i of the covariance C with eigenvalue l_i > 0), one point
/// x + a_i sqrt(l_i) v_i: one standard deviation along it (a_i = 1), or the other way (a_i = -1)
/// when that leaves the parameters' bounds, or shortened (|a_i| < 1) when both ways do. To first
/// order an outcome f then has the variance sum_i ((f(p_i) - f(x)) / a_i)^2 = g^T C g, g its
/// gradient (linearized propagation through the parameter Jacobian, one simulation per
/// direction; a secant over one SD rather than a tangent, which the simulated outcomes' small
/// jumps with the mesh would spoil).
///
/// C is the fit's covariance combined with what the bounds say (bounded_covariance): a direction
/// the data barely see gets the spread of the parameters' range, not the fit's thousands of
/// SDs, so its point is not a sliver of a step whose secant magnifies the outcome's jumps; one
/// they do not see at all gets its range's spread instead of none.
struct SigmaPoints {
  Eigen::VectorXd center;               ///< x, the fitted values (user units)
  Eigen::MatrixXd covariance;           ///< C: the points' covariance (the bounds included)
  std::vector<Eigen::VectorXd> points;  ///< p_i
  std::vector<double> scale;            ///< a_i
};

/// The fit's covariance C (Gaussian, linearized) with the bounds as a prior: a parameter known
/// to lie in [lo, hi] is given that range's uniform variance (hi - lo)^2 / 12 as a Gaussian
/// prior, precision P = diag(12 / (hi - lo)^2), and the posterior's covariance is
/// (C^+ + P)^+, C^+ the fit's precision (the pseudo-inverse: zero along the directions the data
/// do not see). A well-determined parameter (SD much below its range) keeps its SD; one the
/// data barely see gets at most its range's spread, and one they do not see at all exactly the
/// prior's (it no longer drops out of the interval). A parameter without finite, ordered bounds
/// gets no prior.
Eigen::MatrixXd bounded_covariance(const Eigen::MatrixXd& covariance, const Eigen::VectorXd& lower,
                                   const Eigen::VectorXd& upper);

/// Throws mvtwin::Error for inconsistent sizes or non-finite values. A zero (or all-null)
/// covariance gives no points: every outcome's SD is then 0.
SigmaPoints sigma_points(const Eigen::VectorXd& center, const Eigen::MatrixXd& covariance,
                         const Eigen::VectorXd& lower, const Eigen::VectorXd& upper);

/// A point whose simulations failed (a crossing, an inverted element) is moved half way towards
/// the center (its scale a_i halves) and simulated again, `times` times at most: the secant over
/// half an SD linearizes as well, and one failed direction would otherwise leave every
/// outcome's SD unknown. `failed(i)` says whether point i's simulations failed; `rerun(is)`
/// simulates the moved points `is` again. Returns the number of points moved, counted per move.
int halve_failed_points(SigmaPoints* sp, const std::function<bool(size_t)>& failed,
                        const std::function<void(const std::vector<size_t>&)>& rerun,
                        int times = 2);

/// The SD of each outcome (columns) from its value at the center and at each point (rows of
/// `at_points`, in the order of `sp.points`); NaN where any of them is not finite.
Eigen::VectorXd propagated_sd(const SigmaPoints& sp, const Eigen::VectorXd& at_center,
                              const Eigen::MatrixXd& at_points);

/// The SD of the difference of two outcomes computed at the same points (their correlation
/// through the shared parameters counts): whether two options can be told apart.
double difference_sd(const SigmaPoints& sp, double a_center, const Eigen::VectorXd& a_points,
                     double b_center, const Eigen::VectorXd& b_points);

/// Two options cannot be told apart when their difference lies within the 95 % interval of the
/// difference (1.96 SD).
inline constexpr double kZ95 = 1.959963984540054;

/// A calibration's posterior as the clip plan uses it: the fitted parameters' space (their
/// names, bounds, the full fitted set as the base) and covariance. `usable` is false (with a
/// reason) when the file holds no covariance.
struct CalibrationPosterior {
  bool usable = false;
  std::string why_not;
  std::string selection;  ///< comma-separated parameter names
  Eigen::VectorXd fitted, lower, upper;
  Eigen::MatrixXd covariance;
  ValveParameters base;
  std::vector<std::string> unidentified;  ///< names whose SD the data do not give
  /// The base with the fitted parameters set to `x`.
  ValveParameters apply(const Eigen::VectorXd& x) const;
};
CalibrationPosterior posterior_of(const CalibrationRecord& record);

/// Each fitted parameter's SD with its bounds as a prior (the square roots of
/// bounded_covariance's diagonal), in the record's order: what the clip plan's intervals use,
/// where the record's own `sd` is the data's alone (thousands of SDs for a parameter the data
/// barely see, none for one they do not see). NaN for every parameter when the record holds no
/// finite covariance or no bounds of its size, and for one that neither the data nor finite
/// bounds limit.
Eigen::VectorXd bounded_sd(const CalibrationRecord& record);

}  // namespace mvtwin::inverse
