#include "mvtwin/inverse/outcome_uncertainty.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

#include "mvtwin/core/error.h"
#include "mvtwin/core/nan.h"
#include "mvtwin/inverse/parameter_space.h"

namespace mvtwin::inverse {

namespace {

/// The largest a in (0, 1] with x + a d inside [lo, hi] (0 when x itself is outside).
double room(const Eigen::VectorXd& x, const Eigen::VectorXd& d, const Eigen::VectorXd& lo,
            const Eigen::VectorXd& hi) {
  double a = 1.0;
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    if (d[i] > 0) a = std::min(a, (hi[i] - x[i]) / d[i]);
    if (d[i] < 0) a = std::min(a, (lo[i] - x[i]) / d[i]);
  }
  return std::max(a, 0.0);
}
}  // namespace

Eigen::MatrixXd bounded_covariance(const Eigen::MatrixXd& covariance, const Eigen::VectorXd& lower,
                                   const Eigen::VectorXd& upper) {
  const Eigen::Index n = covariance.rows();
  if (covariance.cols() != n || lower.size() != n || upper.size() != n)
    throw Error("outcome uncertainty: the covariance and the bounds differ in size");
  Eigen::VectorXd precision = Eigen::VectorXd::Zero(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double w = upper[i] - lower[i];
    if (std::isfinite(w) && w > 0) precision[i] = 12.0 / (w * w);
  }
  // The fit's precision C^+ (zero along the directions the data do not see: the pseudo-inverse
  // of the covariance, whose null space they are) plus the prior's, inverted the same way (a
  // direction neither the data nor finite bounds limit stays out).
  auto pseudo_inverse = [](const Eigen::MatrixXd& m) {
    const Eigen::MatrixXd sym = 0.5 * (m + m.transpose());
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(sym);
    const Eigen::VectorXd l = es.eigenvalues();
    const double top = l.size() > 0 ? l.cwiseAbs().maxCoeff() : 0.0;
    Eigen::VectorXd inv = Eigen::VectorXd::Zero(l.size());
    for (Eigen::Index k = 0; k < l.size(); ++k)
      if (l[k] > 1e-12 * top && l[k] > 0) inv[k] = 1.0 / l[k];
    const Eigen::MatrixXd r = es.eigenvectors() * inv.asDiagonal() * es.eigenvectors().transpose();
    return Eigen::MatrixXd(0.5 * (r + r.transpose()));
  };
  return pseudo_inverse(pseudo_inverse(covariance) + Eigen::MatrixXd(precision.asDiagonal()));
}

SigmaPoints sigma_points(const Eigen::VectorXd& center, const Eigen::MatrixXd& covariance,
                         const Eigen::VectorXd& lower, const Eigen::VectorXd& upper) {
  const Eigen::Index n = center.size();
  if (covariance.rows() != n || covariance.cols() != n || lower.size() != n || upper.size() != n)
    throw Error("outcome uncertainty: the covariance, bounds and center differ in size");
  if (!center.allFinite() || !covariance.allFinite())
    throw Error("outcome uncertainty: the center or the covariance is not finite");
  SigmaPoints sp;
  sp.center = center;
  sp.covariance = bounded_covariance(covariance, lower, upper);
  if (n == 0) return sp;
  const Eigen::MatrixXd& c = sp.covariance;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(c);
  const double top = es.eigenvalues().cwiseAbs().maxCoeff();
  for (Eigen::Index k = 0; k < n; ++k) {
    const double l = es.eigenvalues()[k];
    if (!(l > 1e-12 * top) || !(l > 0)) continue;  // a direction the data do not determine
    const Eigen::VectorXd d = std::sqrt(l) * es.eigenvectors().col(k);
    const double forward = room(center, d, lower, upper);
    const double backward = room(center, -d, lower, upper);
    double a = 1.0;
    if (forward >= 1.0) {
      a = 1.0;
    } else if (backward >= 1.0) {
      a = -1.0;
    } else if (std::max(forward, backward) > 1e-6) {
      a = forward >= backward ? forward : -backward;
    } else {
      continue;  // pinned at both bounds: no room to move
    }
    sp.points.push_back(center + a * d);
    sp.scale.push_back(a);
  }
  return sp;
}

int halve_failed_points(SigmaPoints* sp, const std::function<bool(size_t)>& failed,
                        const std::function<void(const std::vector<size_t>&)>& rerun, int times) {
  int moved = 0;
  for (int t = 0; t < times; ++t) {
    std::vector<size_t> again;
    for (size_t i = 0; i < sp->points.size(); ++i)
      if (failed(i)) {
        sp->points[i] = sp->center + 0.5 * (sp->points[i] - sp->center);
        sp->scale[i] *= 0.5;
        again.push_back(i);
      }
    if (again.empty()) break;
    moved += static_cast<int>(again.size());
    rerun(again);
  }
  return moved;
}

Eigen::VectorXd propagated_sd(const SigmaPoints& sp, const Eigen::VectorXd& at_center,
                              const Eigen::MatrixXd& at_points) {
  if (at_points.rows() != static_cast<Eigen::Index>(sp.points.size()) ||
      (at_points.rows() > 0 && at_points.cols() != at_center.size()))
    throw Error("outcome uncertainty: one row of outcomes per sigma point expected");
  Eigen::VectorXd var = Eigen::VectorXd::Zero(at_center.size());
  for (Eigen::Index i = 0; i < at_points.rows(); ++i) {
    const Eigen::VectorXd d =
        (at_points.row(i).transpose() - at_center) / sp.scale[static_cast<size_t>(i)];
    var += d.cwiseProduct(d);
  }
  Eigen::VectorXd sd = var.cwiseSqrt();
  for (Eigen::Index k = 0; k < sd.size(); ++k)
    if (!std::isfinite(sd[k]) || !std::isfinite(at_center[k])) sd[k] = kNaN;
  return sd;
}

double difference_sd(const SigmaPoints& sp, double a_center, const Eigen::VectorXd& a_points,
                     double b_center, const Eigen::VectorXd& b_points) {
  Eigen::VectorXd c(1);
  c[0] = a_center - b_center;
  Eigen::MatrixXd p(static_cast<Eigen::Index>(sp.points.size()), 1);
  if (a_points.size() != p.rows() || b_points.size() != p.rows())
    throw Error("outcome uncertainty: one outcome per sigma point expected");
  p.col(0) = a_points - b_points;
  return propagated_sd(sp, c, p)[0];
}

ValveParameters CalibrationPosterior::apply(const Eigen::VectorXd& x) const {
  return ParameterSpace(selection, base).apply(x);
}

CalibrationPosterior posterior_of(const CalibrationRecord& r) {
  CalibrationPosterior post;
  post.base = r.parameters;
  const Eigen::Index n = static_cast<Eigen::Index>(r.names.size());
  if (n == 0) {
    post.why_not = "the calibration fitted no parameters";
    return post;
  }
  if (r.covariance.rows() != n || r.covariance.cols() != n || !r.covariance.allFinite()) {
    post.why_not = "the calibration file holds no covariance";
    return post;
  }
  for (const auto& name : r.names) post.selection += (post.selection.empty() ? "" : ",") + name;
  // The space orders its parameters as the catalogue does; the record's order may differ.
  const ParameterSpace space(post.selection, r.parameters);
  std::vector<Eigen::Index> at(static_cast<size_t>(n), -1);
  for (Eigen::Index i = 0; i < n; ++i)
    for (int k = 0; k < space.size(); ++k)
      if (space.specs()[static_cast<size_t>(k)].name == r.names[static_cast<size_t>(i)]) at[i] = k;
  post.fitted = space.values_of(r.parameters);
  post.lower = space.lower();
  post.upper = space.upper();
  post.covariance = Eigen::MatrixXd::Zero(n, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    if (at[static_cast<size_t>(i)] < 0) {
      post.why_not = "parameter '" + r.names[static_cast<size_t>(i)] + "' is not fittable";
      return post;
    }
    for (Eigen::Index j = 0; j < n; ++j)
      post.covariance(at[static_cast<size_t>(i)], at[static_cast<size_t>(j)]) = r.covariance(i, j);
    if (i < r.sd.size() && !std::isfinite(r.sd[i]))
      post.unidentified.push_back(r.names[static_cast<size_t>(i)]);
  }
  post.usable = true;
  return post;
}

Eigen::VectorXd bounded_sd(const CalibrationRecord& r) {
  const Eigen::Index n = static_cast<Eigen::Index>(r.names.size());
  Eigen::VectorXd sd = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::quiet_NaN());
  if (n == 0 || r.covariance.rows() != n || r.covariance.cols() != n || !r.covariance.allFinite() ||
      r.lower.size() != n || r.upper.size() != n)
    return sd;
  const Eigen::MatrixXd c = bounded_covariance(r.covariance, r.lower, r.upper);
  for (Eigen::Index i = 0; i < n; ++i) {
    // Neither the data nor finite bounds limit it: unknown, not zero.
    const bool bounded = std::isfinite(r.upper[i] - r.lower[i]) && r.upper[i] > r.lower[i];
    if (bounded || c(i, i) > 0) sd[i] = std::sqrt(std::max(0.0, c(i, i)));
  }
  return sd;
}

}  // namespace mvtwin::inverse
