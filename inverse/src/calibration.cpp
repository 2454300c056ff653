#include "mvtwin/inverse/calibration.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <mutex>

#include <ceres/ceres.h>
#include <Eigen/Eigenvalues>
#include <nlopt.hpp>

#include "mvtwin/core/error.h"
#include "mvtwin/core/nan.h"
#include "mvtwin/forward/closure_settings.h"

namespace mvtwin::inverse {
namespace {

/// Evaluations through one place: history, best point, progress.
class Tracker {
 public:
  /// `offset`: simulations run before this tracker's (on another model), for the counts.
  Tracker(ClosureObjective& objective, const CalibrationOptions& options, int offset = 0)
      : objective_(objective), options_(options), offset_(offset) {}

  Evaluation evaluate(const Eigen::VectorXd& x) { return record(x, objective_.evaluate(x)); }
  std::vector<Evaluation> evaluate_many(const std::vector<Eigen::VectorXd>& xs) {
    std::vector<Evaluation> es = objective_.evaluate_many(xs, options_.jobs);
    for (size_t i = 0; i < xs.size(); ++i) record(xs[i], es[i]);
    return es;
  }
  const Eigen::VectorXd& best_x() const { return best_x_; }
  double best() const { return best_; }
  std::vector<HistoryEntry> history() const { return history_; }
  /// Penalty for a failed candidate: clearly worse than anything seen, but finite so that a
  /// model-based optimizer's model stays usable.
  double penalty() const { return std::isfinite(worst_) ? 2.0 * worst_ + 1.0 : 50.0; }
  int iteration = 0;

 private:
  Evaluation record(const Eigen::VectorXd& x, Evaluation e) {
    std::lock_guard<std::mutex> lock(m_);
    if (e.cached) return e;
    if (e.ok) {
      worst_ = std::isfinite(worst_) ? std::max(worst_, e.mean_mm) : e.mean_mm;
      if (!(e.mean_mm >= best_)) {
        best_ = e.mean_mm;
        best_x_ = x;
      }
    }
    history_.push_back({offset_ + objective_.simulations(), e.ok ? e.mean_mm : kNaN, best_, x});
    if (options_.progress) options_.progress(iteration, best_, offset_ + objective_.simulations());
    return e;
  }
  ClosureObjective& objective_;
  const CalibrationOptions& options_;
  int offset_ = 0;
  std::mutex m_;
  Eigen::VectorXd best_x_;
  double best_ = std::numeric_limits<double>::infinity();
  double worst_ = kNaN;
  std::vector<HistoryEntry> history_;
};

nlopt::algorithm nlopt_algorithm(FitMethod m) {
  switch (m) {
    case FitMethod::kBobyqa:
      return nlopt::LN_BOBYQA;
    case FitMethod::kCobyla:
      return nlopt::LN_COBYLA;
    case FitMethod::kNelderMead:
      return nlopt::LN_NELDERMEAD;
    case FitMethod::kSbplx:
      return nlopt::LN_SBPLX;
    case FitMethod::kCeres:
      break;
  }
  throw Error(std::string("calibrate: ") + fit_method_name(m) + " is not an NLopt method");
}

std::string nlopt_result_name(nlopt::result r) {
  switch (r) {
    case nlopt::SUCCESS:
      return "success";
    case nlopt::STOPVAL_REACHED:
      return "stop value reached";
    case nlopt::FTOL_REACHED:
      return "error tolerance reached";
    case nlopt::XTOL_REACHED:
      return "step tolerance reached";
    case nlopt::MAXEVAL_REACHED:
      return "simulation budget used";
    case nlopt::MAXTIME_REACHED:
      return "time limit reached";
    default:
      return "nlopt result " + std::to_string(static_cast<int>(r));
  }
}

struct Scaling {
  Eigen::VectorXd x0, scale, zlo, zhi;
  Eigen::VectorXd x(const double* z) const {
    return x0 + scale.cwiseProduct(Eigen::Map<const Eigen::VectorXd>(z, x0.size()));
  }
};

std::string run_nlopt(Tracker& tr, const Scaling& s, const CalibrationOptions& o, int budget) {
  const int n = static_cast<int>(s.x0.size());
  nlopt::opt opt(nlopt_algorithm(o.method), static_cast<unsigned>(n));
  std::vector<double> lo(s.zlo.data(), s.zlo.data() + n), hi(s.zhi.data(), s.zhi.data() + n);
  opt.set_lower_bounds(lo);
  opt.set_upper_bounds(hi);
  // One scale per parameter as the first step, less where the bounds are closer.
  std::vector<double> step(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) step[i] = std::min(1.0, 0.5 * (hi[i] - lo[i]));
  opt.set_initial_step(step);
  opt.set_xtol_abs(o.step_tolerance);
  opt.set_ftol_abs(o.error_tolerance);
  opt.set_maxeval(budget);
  // BOBYQA and COBYLA start by evaluating the start point and one step along each axis
  // (both directions for BOBYQA): run those in parallel now, so that the optimizer finds
  // them in the objective's cache.
  std::vector<Eigen::VectorXd> first{s.x0};
  if (o.jobs > 1 && (o.method == FitMethod::kBobyqa || o.method == FitMethod::kCobyla)) {
    for (int i = 0; i < n; ++i) {
      for (double sign : {1.0, -1.0}) {
        if (sign < 0 && o.method == FitMethod::kCobyla) continue;
        Eigen::VectorXd z = Eigen::VectorXd::Zero(n);
        z[i] = sign * step[i];
        if (z[i] >= s.zlo[i] && z[i] <= s.zhi[i]) first.push_back(s.x(z.data()));
      }
    }
  }
  tr.evaluate_many(first);
  auto f = [&](const std::vector<double>& z, std::vector<double>&) {
    const Evaluation e = tr.evaluate(s.x(z.data()));
    ++tr.iteration;
    return e.ok ? e.mean_mm : tr.penalty();
  };
  using F = decltype(f);
  opt.set_min_objective([](const std::vector<double>& z, std::vector<double>& g,
                           void* data) { return (*static_cast<F*>(data))(z, g); },
                        &f);
  std::vector<double> z(static_cast<size_t>(n), 0.0);
  double fmin = 0;
  try {
    return nlopt_result_name(opt.optimize(z, fmin));
  } catch (const nlopt::roundoff_limited&) {
    return "round-off limited (the best point is kept)";
  } catch (const std::runtime_error& e) {
    return std::string("nlopt stopped: ") + e.what() + " (the best point is kept)";
  }
}

/// The residuals as Ceres sees them: robustified per residual (Huber: r -> sqrt(rho(r^2))),
/// with a forward-difference Jacobian whose n perturbed simulations run in parallel.
class ClosureCost : public ceres::CostFunction {
 public:
  ClosureCost(Tracker& tr, const Scaling& s, const CalibrationOptions& o, int m)
      : tr_(tr), s_(s), o_(o) {
    set_num_residuals(m);
    mutable_parameter_block_sizes()->push_back(static_cast<int>(s.x0.size()));
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const int n = static_cast<int>(s_.x0.size()), m = num_residuals();
    const double* z = parameters[0];
    std::vector<Eigen::VectorXd> xs{s_.x(z)};
    std::vector<double> h(static_cast<size_t>(n));
    const bool jac = jacobians && jacobians[0];
    if (jac) {
      for (int i = 0; i < n; ++i) {
        // Forward differences, backward at the upper bound.
        h[i] = z[i] + o_.fd_step <= s_.zhi[i] ? o_.fd_step : -o_.fd_step;
        Eigen::VectorXd zi = Eigen::Map<const Eigen::VectorXd>(z, n);
        zi[i] += h[i];
        xs.push_back(s_.x(zi.data()));
      }
    }
    const std::vector<Evaluation> es = tr_.evaluate_many(xs);
    ++tr_.iteration;
    if (!es[0].ok) return false;  // Ceres rejects the step and shrinks its trust region
    Eigen::VectorXd rt(m), dr(m);
    for (int k = 0; k < m; ++k) {
      const double r = es[0].residuals[k], d2 = o_.huber_mm * o_.huber_mm;
      if (r * r <= d2) {
        rt[k] = r;
        dr[k] = 1.0;
      } else {
        const double rho = 2.0 * o_.huber_mm * std::abs(r) - d2;
        rt[k] = std::sqrt(rho);
        dr[k] = o_.huber_mm * (r > 0 ? 1.0 : -1.0) / rt[k];
      }
      residuals[k] = rt[k];
    }
    if (jac) {
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> J(
          jacobians[0], m, n);
      for (int i = 0; i < n; ++i) {
        if (!es[1 + i].ok) {
          J.col(i).setZero();  // this direction failed: no information along it this step
          continue;
        }
        J.col(i) = dr.cwiseProduct(es[1 + i].residuals - es[0].residuals) / h[i];
      }
    }
    return true;
  }

 private:
  Tracker& tr_;
  const Scaling& s_;
  const CalibrationOptions& o_;
};

std::string run_ceres(Tracker& tr, const Scaling& s, const CalibrationOptions& o, int m,
                      int budget) {
  const int n = static_cast<int>(s.x0.size());
  std::vector<double> z(static_cast<size_t>(n), 0.0);
  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  ClosureCost cost(tr, s, o, m);
  problem.AddResidualBlock(&cost, nullptr, z.data());
  for (int i = 0; i < n; ++i) {
    problem.SetParameterLowerBound(z.data(), i, s.zlo[i]);
    problem.SetParameterUpperBound(z.data(), i, s.zhi[i]);
  }
  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = std::max(1, budget / (n + 1));
  so.parameter_tolerance = 1e-3;
  so.function_tolerance = 1e-4;
  so.initial_trust_region_radius = 1.0;  // one scale per parameter
  so.num_threads = 1;                    // the parallelism is in the Jacobian's simulations
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  return std::string("ceres: ") + summary.message;
}

}  // namespace

void fill_uncertainty(const Eigen::MatrixXd& J, double noise_mm, CalibrationResult* r) {
  const int n = static_cast<int>(J.cols());
  r->noise_mm = noise_mm;
  const Eigen::MatrixXd JtJ = J.transpose() * J;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(JtJ);
  const double top = es.eigenvalues().cwiseAbs().maxCoeff();
  Eigen::MatrixXd inv = Eigen::MatrixXd::Zero(n, n);
  std::vector<bool> in_null(static_cast<size_t>(n), false);
  for (int k = 0; k < n; ++k) {
    const double l = es.eigenvalues()[k];
    if (l > 1e-10 * top && l > 0) {
      inv += es.eigenvectors().col(k) * es.eigenvectors().col(k).transpose() / l;
    } else {
      // A direction the data do not see: every parameter it moves is unidentified.
      for (int i = 0; i < n; ++i)
        if (std::abs(es.eigenvectors()(i, k)) > 0.1) in_null[i] = true;
    }
  }
  r->covariance = noise_mm * noise_mm * inv;
  r->sd.resize(n);
  r->correlation.resize(n, n);
  r->identified.assign(static_cast<size_t>(n), false);
  for (int i = 0; i < n; ++i) {
    r->sd[i] = in_null[i] ? kNaN : std::sqrt(std::max(0.0, r->covariance(i, i)));
    for (int j = 0; j < n; ++j) {
      const double d = std::sqrt(r->covariance(i, i) * r->covariance(j, j));
      r->correlation(i, j) = in_null[i] || in_null[j] || !(d > 0) ? kNaN : r->covariance(i, j) / d;
    }
    r->identified[i] =
        !in_null[i] && i < static_cast<int>(r->specs.size()) && r->sd[i] <= r->specs[i].scale;
  }
}

const char* fit_method_name(FitMethod m) {
  switch (m) {
    case FitMethod::kBobyqa:
      return "bobyqa";
    case FitMethod::kCobyla:
      return "cobyla";
    case FitMethod::kNelderMead:
      return "neldermead";
    case FitMethod::kSbplx:
      return "sbplx";
    case FitMethod::kCeres:
      return "ceres";
  }
  return "unknown";
}

std::optional<FitMethod> parse_fit_method(const std::string& name) {
  for (int k = 0; k < kNumFitMethods; ++k) {
    const auto m = static_cast<FitMethod>(k);
    if (name == fit_method_name(m)) return m;
  }
  return std::nullopt;
}

std::map<std::string, FitMethod> fit_methods_by_name() {
  std::map<std::string, FitMethod> m;
  for (int k = 0; k < kNumFitMethods; ++k) {
    const auto f = static_cast<FitMethod>(k);
    m[fit_method_name(f)] = f;
  }
  return m;
}

bool CalibrationOptions::is_valid(std::string* error) const {
  auto bad = [&](const char* m) {
    *error = m;
    return false;
  };
  if (static_cast<int>(method) < 0 || static_cast<int>(method) >= kNumFitMethods)
    return bad("unknown fit method");
  if (jobs < 1) return bad("jobs must be >= 1");
  if (max_simulations < 1) return bad("max_simulations must be >= 1");
  if (!(step_tolerance > 0)) return bad("step_tolerance must be positive");
  if (!(error_tolerance >= 0)) return bad("error_tolerance must be >= 0");
  if (!(huber_mm > 0)) return bad("huber_mm must be positive");
  if (!(fd_step > 0)) return bad("fd_step must be positive");
  for (double d : restlength_scan)
    if (!std::isfinite(d)) return bad("rest-length scan offsets must be finite");
  for (double m : modulus_scan)
    if (!(std::isfinite(m) && m > 0))
      return bad("modulus scan multipliers must be finite and positive");
  if (!std::isfinite(noise_mm)) return bad("noise_mm must be finite");
  if (std::string why; search_model && !search_model->is_valid(&why)) {
    *error = "the search model: " + why;
    return false;
  }
  return true;
}

namespace {

std::string model_size(const forward::ClosureOptions& m) {
  return std::to_string(m.model.ures) + " x " + std::to_string(m.model.vres);
}

/// The start, the rest-length scan and the optimizer on `objective`: fills start,
/// optimizer_start, fitted, error_before_mm, error_after_mm, termination.
void search(ClosureObjective& objective, Tracker& tr, const CalibrationOptions& o,
            CalibrationResult* r) {
  const ParameterSpace& space = objective.space();
  Scaling s;
  s.x0 = space.start();
  s.scale = space.scales();
  s.zlo = (space.lower() - s.x0).cwiseQuotient(s.scale);
  s.zhi = (space.upper() - s.x0).cwiseQuotient(s.scale);
  r->start = s.x0;

  const Evaluation e0 = tr.evaluate(s.x0);
  if (!e0.ok) throw Error("calibrate: the start point cannot be simulated: " + e0.reason);
  r->error_before_mm = e0.mean_mm;

  // Scans: a line of common rest-length offsets and (when the moduli are fitted) a line of
  // common modulus multipliers, both from the start and simulated at once, then the best point
  // of each line combined; the optimizer starts from the best of them and the start.
  std::vector<int> rest, moduli;
  for (int i = 0; i < space.size(); ++i) {
    if (space.specs()[i].group == "restlength") rest.push_back(i);
    if (space.specs()[i].group == "modulus") moduli.push_back(i);
  }
  std::vector<Eigen::VectorXd> line;
  if (!rest.empty()) {
    for (double d : o.restlength_scan) {
      Eigen::VectorXd x = s.x0;
      for (int i : rest) x[i] = std::clamp(x[i] + d, space.lower()[i], space.upper()[i]);
      line.push_back(x);
    }
  }
  const size_t rest_points = line.size();
  if (!moduli.empty()) {
    for (double m : o.modulus_scan) {
      Eigen::VectorXd x = s.x0;
      for (int i : moduli) x[i] = std::clamp(x[i] * m, space.lower()[i], space.upper()[i]);
      line.push_back(x);
    }
  }
  if (!line.empty()) {
    const std::vector<Evaluation> es = tr.evaluate_many(line);
    // The best of each line (where it beats the start), combined.
    auto best_of = [&](size_t begin, size_t end) -> int {
      int best = -1;
      double err = e0.mean_mm;
      for (size_t j = begin; j < end; ++j)
        if (es[j].ok && es[j].mean_mm < err) {
          err = es[j].mean_mm;
          best = static_cast<int>(j);
        }
      return best;
    };
    const int br = best_of(0, rest_points), bm = best_of(rest_points, line.size());
    if (br >= 0 && bm >= 0) {
      Eigen::VectorXd x = line[static_cast<size_t>(br)];
      for (int i : moduli) x[i] = line[static_cast<size_t>(bm)][i];
      tr.evaluate(x);
    }
    if (tr.best() < e0.mean_mm) {
      s.x0 = tr.best_x();
      s.zlo = (space.lower() - s.x0).cwiseQuotient(s.scale);
      s.zhi = (space.upper() - s.x0).cwiseQuotient(s.scale);
    }
  }
  r->optimizer_start = s.x0;

  // The budget counts the simulations before the optimizer too, but leaves it at least a
  // start design's worth.
  const int budget = std::max(2 * space.size() + 2, o.max_simulations - objective.simulations());
  r->termination = o.method == FitMethod::kCeres
                       ? run_ceres(tr, s, o, objective.num_residuals(), budget)
                       : run_nlopt(tr, s, o, budget);
  r->fitted = tr.best_x();
  r->error_after_mm = tr.best();
}

/// The points of the uncertainty's forward differences at x: half a scale along each
/// parameter, backwards at an upper bound; `h` gets the steps.
std::vector<Eigen::VectorXd> difference_points(const ParameterSpace& space,
                                               const Eigen::VectorXd& x, Eigen::VectorXd* h) {
  const int n = space.size();
  std::vector<Eigen::VectorXd> xs;
  h->resize(n);
  for (int i = 0; i < n; ++i) {
    const double scale = space.scales()[i];
    (*h)[i] = (x[i] + 0.5 * scale <= space.upper()[i] ? 0.5 : -0.5) * scale;
    Eigen::VectorXd xi = x;
    xi[i] += (*h)[i];
    xs.push_back(xi);
  }
  return xs;
}

/// The Jacobian of the distances from evaluations at x (`at`) and at difference_points();
/// zero columns where a perturbed simulation failed.
Eigen::MatrixXd difference_jacobian(const Evaluation& at, const std::vector<Evaluation>& es,
                                    const Eigen::VectorXd& h, int m) {
  const auto n = h.size();
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(m, n);
  for (Eigen::Index i = 0; i < n; ++i)
    if (es[static_cast<size_t>(i)].ok && at.ok)
      J.col(i) = (es[static_cast<size_t>(i)].residuals - at.residuals) / h[i];
  return J;
}

double residual_rms(const Evaluation& e) {
  return e.ok ? std::sqrt(e.residuals.squaredNorm() / static_cast<double>(e.residuals.size()))
              : kNaN;
}

void count_work(const ClosureObjective& obj, CalibrationResult* r) {
  r->simulations += obj.simulations();
  r->failed_simulations += obj.failed_simulations();
  r->cache_hits += obj.cache_hits();
  for (const auto& [why, k] : obj.failures_by_outcome()) r->failures_by_outcome[why] += k;
}

}  // namespace

std::vector<Eigen::VectorXd> gauss_newton_steps(const ParameterSpace& space,
                                                const Eigen::VectorXd& x, const Eigen::VectorXd& r,
                                                const Eigen::MatrixXd& J,
                                                const std::vector<double>& dampings) {
  const Eigen::VectorXd scale = space.scales();
  const Eigen::MatrixXd Jz = J * scale.asDiagonal();
  const Eigen::MatrixXd A = Jz.transpose() * Jz;
  const Eigen::VectorXd g = Jz.transpose() * r;
  const double mean_diag = A.diagonal().mean();
  std::vector<Eigen::VectorXd> out;
  if (!(mean_diag > 0) || !g.allFinite()) return out;
  for (double lambda : dampings) {
    Eigen::MatrixXd M = A;
    // Marquardt's scaling, with a floor so that a direction the data do not see stays put.
    for (Eigen::Index i = 0; i < M.rows(); ++i)
      M(i, i) += lambda * std::max(A(i, i), 1e-6 * mean_diag);
    Eigen::VectorXd dz = M.ldlt().solve(-g);
    if (!dz.allFinite()) continue;
    const double longest = dz.cwiseAbs().maxCoeff();
    if (longest > 1.0) dz /= longest;
    Eigen::VectorXd y = x + scale.cwiseProduct(dz);
    y = y.cwiseMax(space.lower()).cwiseMin(space.upper());
    out.push_back(y);
  }
  return out;
}

std::optional<forward::ClosureOptions> search_model_for(const forward::ClosureOptions& model) {
  // Measured on three virtual patients at the paper's grid (docs/calibration.md): 24 x 24
  // searched to the same fits (within 0.006 mm after the refinement) in 0.71-0.85 of the time;
  // 20 x 30 was faster but failed candidates the finer grid closes and missed one fit by 0.2 mm.
  constexpr double kFactor = 0.8;
  constexpr int kSmallestUres = 25;  // below it a search model saves too little
  if (model.model.ures < kSmallestUres) return std::nullopt;
  forward::ClosureOptions m = model;
  m.model.ures = static_cast<int>(std::lround(kFactor * model.model.ures));
  m.model.vres = static_cast<int>(std::lround(kFactor * model.model.vres));
  // Settling cut after 1 s (24 x 24: within 0.06 mm mean of rest on virtual patients 1-5): the
  // fits of at-rest observations came out as close (virtual patients 11-15, 0.529 against 0.532
  // mm) in 56 s instead of 75 (docs/calibration.md, "The closed valve at rest").
  constexpr double kSearchSettleS = 1.0;
  m.settle_max_s = std::min(m.settle_max_s, kSearchSettleS);
  return m;
}

CalibrationResult calibrate(ClosureObjective& objective, const CalibrationOptions& o) {
  if (std::string why; !o.is_valid(&why)) throw Error("calibrate: " + why);
  const auto t0 = std::chrono::steady_clock::now();
  const ParameterSpace& space = objective.space();
  const forward::ClosureOptions& model = objective.options().simulation;
  CalibrationResult r;
  r.method = fit_method_name(o.method);
  r.specs = space.specs();

  const bool two_models = o.search_model && forward::describe_result_options(*o.search_model) !=
                                                forward::describe_result_options(model);
  std::vector<HistoryEntry> history;
  Evaluation at;      // the fine model at the point the Jacobian is taken
  Eigen::VectorXd h;  // its steps
  Eigen::MatrixXd J;  // the fine model's Jacobian there
  Evaluation kept;    // the fine model at the fit
  if (!two_models) {
    if (o.stage) o.stage("search on the " + model_size(model) + " model");
    Tracker tr(objective, o);
    search(objective, tr, o, &r);
    // Uncertainty: the Jacobian at the fit by forward differences (n simulations in parallel).
    const std::vector<Evaluation> es = tr.evaluate_many(difference_points(space, r.fitted, &h));
    at = objective.evaluate(r.fitted);  // from the cache
    J = difference_jacobian(at, es, h, objective.num_residuals());
    kept = at;
    history = tr.history();
  } else {
    ObjectiveOptions so = objective.options();
    so.simulation = *o.search_model;
    ClosureObjective coarse(objective.patient(), space, so);
    if (o.stage) o.stage("search on the " + model_size(so.simulation) + " model");
    Tracker ts(coarse, o);
    CalibrationResult sr;
    search(coarse, ts, o, &sr);
    r.start = sr.start;
    r.optimizer_start = sr.optimizer_start;
    r.termination = sr.termination;
    r.search_fitted = sr.fitted;
    r.search_error_before_mm = sr.error_before_mm;
    r.search_error_after_mm = sr.error_after_mm;
    r.search_simulations = coarse.simulations();
    count_work(coarse, &r);
    history = ts.history();

    // Refine on the model: the start (for the error before), the search's fit and the
    // Jacobian there, all at once; then the damped Gauss-Newton steps, at once.
    if (o.stage) o.stage("refine on the " + model_size(model) + " model");
    Tracker tf(objective, o, r.search_simulations);
    std::vector<Eigen::VectorXd> xs{r.start, r.search_fitted};
    for (const Eigen::VectorXd& x : difference_points(space, r.search_fitted, &h)) xs.push_back(x);
    const std::vector<Evaluation> es = tf.evaluate_many(xs);
    if (!es[0].ok) throw Error("calibrate: the start point cannot be simulated: " + es[0].reason);
    r.error_before_mm = es[0].mean_mm;
    at = es[1];
    if (!at.ok) {
      throw Error("calibrate: the search model's fit cannot be simulated on the " +
                  model_size(model) + " model (" + at.reason +
                  "); calibrate without the search model");
    }
    J = difference_jacobian(at, {es.begin() + 2, es.end()}, h, objective.num_residuals());
    r.fitted = r.search_fitted;
    kept = at;
    const std::vector<double> dampings{0.01, 0.3};
    const std::vector<Eigen::VectorXd> steps =
        gauss_newton_steps(space, r.search_fitted, at.residuals, J, dampings);
    const std::vector<Evaluation> ss = tf.evaluate_many(steps);
    int best_step = -1;
    for (size_t k = 0; k < ss.size(); ++k) {
      if (ss[k].ok && ss[k].mean_mm < kept.mean_mm) {
        kept = ss[k];
        r.fitted = steps[k];
        best_step = static_cast<int>(k);
      }
    }
    // Never worse than the start on the model: the search model's optimum can lie off the
    // model's (a flail seen on a coarse grid), and the start was simulated on the model above.
    const bool start_kept = es[0].mean_mm < kept.mean_mm;
    if (start_kept) {
      kept = es[0];
      r.fitted = r.start;
    }
    char line[200];
    if (start_kept) {
      std::snprintf(line, sizeof line,
                    "start kept (the search's fit and its Gauss-Newton steps were worse on the "
                    "model; the uncertainty is the search fit's)");
    } else if (best_step < 0) {
      std::snprintf(line, sizeof line, "Gauss-Newton step not kept (no damping lowered the error)");
    } else {
      std::snprintf(line, sizeof line, "Gauss-Newton step kept (damping %g)",
                    dampings[static_cast<size_t>(best_step)]);
    }
    char errors[80];
    std::snprintf(errors, sizeof errors, ": %.4f -> %.4f mm on the ", at.mean_mm, kept.mean_mm);
    r.refinement = line + std::string(errors) + model_size(model) + " model";
    for (const HistoryEntry& e : tf.history()) history.push_back(e);
  }
  r.error_after_mm = kept.mean_mm;
  r.parameters = space.apply(r.fitted);
  // Uncertainty from J (at the fit, or with a search model at the search's fit: the
  // refinement's step is small against the scales) and the residual RMS at the fit.
  const double rms = residual_rms(kept);
  fill_uncertainty(J, o.noise_mm > 0 ? o.noise_mm : rms, &r);

  r.history = std::move(history);
  count_work(objective, &r);
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

CalibrationRecord make_calibration_record(const CalibrationResult& r, const Patient& p,
                                          const forward::ClosureOptions& sim,
                                          const CalibrationOptions& o) {
  CalibrationRecord c;
  c.patient_id = p.id;
  c.synthetic = p.synthetic;
  c.provenance.seed = p.provenance.seed;
  c.options = forward::describe_options(sim);
  c.options.emplace_back("fit_method", fit_method_name(o.method));
  c.options.emplace_back("fit_jobs", std::to_string(o.jobs));
  c.options.emplace_back("fit_max_simulations", std::to_string(o.max_simulations));
  c.options.emplace_back("fit_step_tolerance", std::to_string(o.step_tolerance));
  c.options.emplace_back("fit_error_tolerance", std::to_string(o.error_tolerance));
  c.options.emplace_back("fit_huber_mm", std::to_string(o.huber_mm));
  c.options.emplace_back("fit_fd_step", std::to_string(o.fd_step));
  auto list = [](const std::vector<double>& v) {
    std::string t;
    for (double x : v) t += (t.empty() ? "" : ",") + std::to_string(x);
    return t.empty() ? std::string("none") : t;
  };
  c.options.emplace_back("fit_restlength_scan", list(o.restlength_scan));
  c.options.emplace_back("fit_modulus_scan", list(o.modulus_scan));
  // The search model by its differences from the fit's model.
  std::string search = "none";
  if (r.search_simulations > 0 && o.search_model) {
    const auto model = forward::describe_result_options(sim);
    search.clear();
    for (const auto& kv : forward::describe_result_options(*o.search_model))
      if (std::find(model.begin(), model.end(), kv) == model.end())
        search += (search.empty() ? "" : ",") + kv.first + "=" + kv.second;
  }
  c.options.emplace_back("fit_search_model", search);
  c.search_simulations = r.search_simulations;
  c.search_error_before_mm = r.search_error_before_mm;
  c.search_error_after_mm = r.search_error_after_mm;
  c.refinement = r.refinement;
  c.method = r.method;
  c.termination = r.termination;
  const auto n = static_cast<Eigen::Index>(r.specs.size());
  c.lower.resize(n);
  c.upper.resize(n);
  c.truth = Eigen::VectorXd::Constant(n, kNaN);
  for (Eigen::Index i = 0; i < n; ++i) {
    const ParameterSpec& s = r.specs[i];
    c.names.push_back(s.name);
    c.units.push_back(s.unit);
    c.lower[i] = s.lower;
    c.upper[i] = s.upper;
    c.identified.push_back(r.identified[i] ? 1 : 0);
    if (p.truth) {
      ValveParameters t = p.truth->parameters;
      t.for_each([&](const std::string& name, double v, const char*) {
        if (name == s.name) c.truth[i] = v / s.to_internal;
      });
    }
  }
  c.start = r.start;
  c.fitted = r.fitted;
  c.sd = r.sd;
  c.covariance = r.covariance;
  c.correlation = r.correlation;
  c.noise_mm = r.noise_mm;
  c.parameters = r.parameters;
  c.error_before_mm = r.error_before_mm;
  c.error_after_mm = r.error_after_mm;
  c.simulations = r.simulations;
  c.failed_simulations = r.failed_simulations;
  c.cache_hits = r.cache_hits;
  c.wall_s = r.wall_s;
  c.history_x.resize(static_cast<Eigen::Index>(r.history.size()), n);
  for (size_t h = 0; h < r.history.size(); ++h) {
    c.history_simulation.push_back(r.history[h].simulation);
    c.history_error_mm.push_back(r.history[h].error_mm);
    c.history_best_mm.push_back(r.history[h].best_mm);
    c.history_x.row(static_cast<Eigen::Index>(h)) = r.history[h].x.transpose();
  }
  return c;
}

}  // namespace mvtwin::inverse
