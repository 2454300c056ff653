#include "mvtwin/inverse/closure_objective.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "mvtwin/core/error.h"
#include "mvtwin/core/point_to_mesh_distance.h"
#include "parallel_indices.h"

namespace mvtwin::inverse {
namespace {

using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// The grid points below the annulus row (the annulus is prescribed, not fitted).
Points leaflet_points(const LeafletGrid& g) {
  return g.points().bottomRows(g.points().rows() - g.ures());
}

}  // namespace

ClosureObjective::ClosureObjective(const Patient& patient, ParameterSpace space,
                                   ObjectiveOptions options)
    : patient_(&patient), space_(std::move(space)), options_(std::move(options)) {
  const ValveSequence& seq = patient.sequence;
  if (seq.end_diastole < 0 || seq.first_closed <= seq.end_diastole) {
    throw Error("objective: patient '" + patient.id +
                "' has no end-diastolic and first closed frame");
  }
  const int first = options_.all_closing_frames ? seq.end_diastole + 1 : seq.first_closed;
  for (int f = first; f <= seq.first_closed; ++f) {
    if (seq.frames[f].la_surface) frames_.push_back(f);
  }
  if (frames_.empty() || frames_.back() != seq.first_closed) {
    throw Error("objective: patient '" + patient.id +
                "' has no observed closed leaflet surface (frame " +
                std::to_string(seq.first_closed) +
                "); a virtual patient gets one from `mvtwin phantom --simulate-closure`");
  }
  std::string err;
  if (!options_.simulation.is_valid(&err)) throw Error("objective: " + err);
  for (int f : frames_) {
    const LeafletGrid& g = *seq.frames[f].la_surface;
    if (!g.points().allFinite()) {
      throw Error("objective: the observed surface of frame " + std::to_string(f) +
                  " has non-finite coordinates");
    }
    observed_meshes_.push_back(g.triangulate());
    observed_points_.push_back(leaflet_points(g));
  }
  simulated_points_per_frame_ =
      options_.simulation.model.ures * (options_.simulation.model.vres - 1);
  num_residuals_ = 0;
  for (const auto& p : observed_points_)
    num_residuals_ += static_cast<int>(p.rows()) + simulated_points_per_frame_;
}

forward::ClosureOptions ClosureObjective::simulation_options() const {
  forward::ClosureOptions o = options_.simulation;
  o.progress = nullptr;
  if (options_.all_closing_frames) {
    // Dense enough to find the state at each frame time (0.02 s of simulated time).
    o.record_every = std::max(1, static_cast<int>(std::lround(0.02 / o.dt)));
  } else {
    o.record_every = 0;  // the end state only
  }
  o.orifice_refine = 0;  // a candidate is compared by its surface only
  return o;
}

forward::ClosureResult ClosureObjective::simulate(const Eigen::VectorXd& x) const {
  forward::ClosureOptions o = simulation_options();
  o.record_every = options_.simulation.record_every;
  o.orifice_refine = options_.simulation.orifice_refine;
  return forward::simulate_closure(patient_->sequence, space_.apply(x), o);
}

Evaluation ClosureObjective::compare(const forward::ClosureResult& r) const {
  Evaluation e;
  try {
    if (!r.summary.converged()) {
      e.outcome = r.summary.outcome;
      e.reason = r.summary.reason;
    } else {
      e.residuals.resize(num_residuals_);
      int k = 0;
      const ValveSequence& seq = patient_->sequence;
      for (size_t i = 0; i < frames_.size(); ++i) {
        const double t = seq.frames[frames_[i]].time_s;
        const forward::ClosureSample* s = &r.samples.back();
        if (frames_[i] != seq.first_closed) {
          for (const auto& c : r.samples)
            if (std::abs(c.observed_time_s - t) < std::abs(s->observed_time_s - t)) s = &c;
        }
        const Points sim = leaflet_points(s->la_surface);
        if (!sim.allFinite()) throw Error("non-finite simulated surface");
        const std::vector<double> a =
            point_to_mesh_distances(observed_points_[i], s->la_surface.triangulate());
        const std::vector<double> b = point_to_mesh_distances(sim, observed_meshes_[i]);
        if (k + static_cast<int>(a.size() + b.size()) > num_residuals_)
          throw Error("objective: the simulation's grid differs from the objective's");
        for (double d : a) e.residuals[k++] = d;
        for (double d : b) e.residuals[k++] = d;
      }
      if (k != num_residuals_) throw Error("objective: residual count changed");
      e.mean_mm = e.residuals.mean();
      e.ok = std::isfinite(e.mean_mm);
      e.outcome = e.ok ? Outcome::kConverged : Outcome::kNonFiniteState;
      if (!e.ok) e.reason = "non-finite distances";
    }
  } catch (const std::exception& ex) {
    e.ok = false;
    e.outcome = Outcome::kInvalidInput;
    e.reason = ex.what();
  }
  if (!e.ok) e.residuals.resize(0);
  e.wall_s = r.summary.wall_s;
  return e;
}

Evaluation ClosureObjective::compute(const Eigen::VectorXd& x) const {
  Evaluation e;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    const ValveParameters par = space_.apply(x);
    if (options_.force_failure && options_.force_failure(par)) {
      e.reason = "forced failure (test)";
    } else {
      e = compare(forward::simulate_closure(patient_->sequence, par, simulation_options()));
    }
  } catch (const std::exception& ex) {
    e.ok = false;
    e.outcome = Outcome::kInvalidInput;
    e.reason = ex.what();
    e.residuals.resize(0);
  }
  e.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return e;
}

Evaluation ClosureObjective::evaluate(const Eigen::VectorXd& x) {
  // Points equal to 1e-9 of each parameter's scale are the same point (an optimizer's x0 + h
  // and the point evaluated ahead of it may differ in the last bits).
  std::vector<double> key(static_cast<size_t>(x.size()));
  const Eigen::VectorXd sc = space_.scales();
  for (Eigen::Index i = 0; i < x.size(); ++i) key[i] = std::round(x[i] / (1e-9 * sc[i]));
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = cache_.find(key);
    if (it != cache_.end()) {
      ++hits_;
      Evaluation e = it->second;
      e.cached = true;
      return e;
    }
  }
  Evaluation e = compute(x);
  std::lock_guard<std::mutex> lock(mutex_);
  ++simulations_;
  if (!e.ok) {
    ++failed_;
    ++failures_[outcome_name(e.outcome)];
  }
  cache_.emplace(key, e);
  return e;
}

std::vector<Evaluation> ClosureObjective::evaluate_many(const std::vector<Eigen::VectorXd>& xs,
                                                        int jobs) {
  std::vector<Evaluation> out(xs.size());
  parallel_indices(xs.size(), jobs, [&](size_t i) { out[i] = evaluate(xs[i]); });
  return out;
}

int ClosureObjective::simulations() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return simulations_;
}
int ClosureObjective::failed_simulations() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return failed_;
}
std::map<std::string, int> ClosureObjective::failures_by_outcome() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return failures_;
}
int ClosureObjective::cache_hits() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return hits_;
}

}  // namespace mvtwin::inverse
