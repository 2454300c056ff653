#include "mvtwin/forward/closure_simulation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <tuple>

#include "mvtwin/core/error.h"
#include "mvtwin/core/stopwatch.h"
#include "mvtwin/forward/closure_integrator.h"
#include "mvtwin/forward/closure_scene.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/forward/step_size_control.h"

namespace mvtwin::forward {
namespace {

using Clock = std::chrono::steady_clock;
/// Settling's raised Newton iterations stop once a correction moves no free node by more than
/// this share of settle_mm (the motion that counts as rest).
constexpr double kSettleCorrectionShare = 0.25;

/// The closure of a built scene; wall_s counts from t_start (the scene's build included). A
/// failed clip phase is run again twice as long, at most kClipPhaseRetries times.
ClosureResult simulate_scene(const ClosureScene& scene, const ClosureOptions& opt,
                             Clock::time_point t_start);

/// One attempt; *clip_phase_failed says whether it stopped in the clip phase.
ClosureResult simulate_once(const ClosureScene& scene, const ClosureOptions& opt,
                            Clock::time_point t_start, bool* clip_phase_failed);

}  // namespace

bool ClosureOptions::is_valid(std::string* error) const {
  if (!model.is_valid(error)) return false;
  auto bad = [&](const std::string& m) {
    *error = m;
    return false;
  };
  if (!(dt > 0 && dt <= 0.5)) return bad("dt must be in (0, 0.5] s");
  if (!(step_error_mm >= 0 && step_error_mm <= 10))
    return bad("step_error_mm must be in [0, 10] mm (0: fixed steps of dt)");
  if (!(max_dt > 0 && max_dt <= 0.5))
    return bad("max_dt must be in (0, 0.5] s (steps never exceed the larger of dt and max_dt)");
  if (!(stretch > 0 && stretch <= 1000)) return bad("stretch must be in (0, 1000]");
  if (!(settle_mm >= 0 && settle_mm <= 10))
    return bad("settle_mm must be in [0, 10] mm (0: no settling)");
  if (!(settle_max_dt > 0 && settle_max_dt <= 10)) return bad("settle_max_dt must be in (0, 10] s");
  if (!(settle_max_s > 0 && settle_max_s <= 1000))
    return bad("settle_max_s must be in (0, 1000] s");
  if (!(density > 0)) return bad("density must be positive");
  if (!(rayleigh_mass >= 0 && rayleigh_stiffness >= 0))
    return bad("Rayleigh coefficients must be >= 0");
  if (!solver.is_valid(error) || !contact.is_valid(error)) return false;
  if (!(inversion_guard >= 0 && inversion_guard < 1))
    return bad("inversion_guard must be in [0, 1) (0: off)");
  if (!(clip_closing_s > 0 && clip_closing_s <= 100))
    return bad("clip_closing_s must be in (0, 100] s");
  if (clip_phase_retries < 0 || clip_phase_retries > 4)
    return bad("clip_phase_retries must be in 0..4");
  for (const ClipOptions& c : clips) {
    if (!(c.anterior_s >= 0 && c.anterior_s <= 1 && c.posterior_s >= 0 && c.posterior_s <= 1 &&
          c.anterior_t >= 0 && c.anterior_t <= 1 && c.posterior_t >= 0 && c.posterior_t <= 1))
      return bad("clip sites must have s and t in [0, 1]");
    if ((c.anterior_s < 0.5) == (c.posterior_s < 0.5))
      return bad("a clip joins the anterior (s < 0.5) and the posterior (s >= 0.5) leaflet");
    if (!(c.stiffness_n_per_mm > 0 && c.stiffness_n_per_mm < 1e4))
      return bad("clip stiffness must be in (0, 1e4) N/mm");
    if (!(c.width_mm >= 0 && c.width_mm <= 30))
      return bad("clip width must be in [0, 30] mm (0: the paper's spring)");
    if (c.width_mm > 0 && !(c.arm_length_mm > 0 && c.arm_length_mm <= 30))
      return bad("a clip device's arm length must be in (0, 30] mm");
    if (!(c.spacer_mm >= 0 && c.spacer_mm <= 20)) return bad("clip spacer must be in [0, 20] mm");
    if (!(c.anterior_insertion_mm >= 0 && c.anterior_insertion_mm <= 30 &&
          c.posterior_insertion_mm >= 0 && c.posterior_insertion_mm <= 30))
      return bad("clip insertions must be in [0, 30] mm (0: from the geometry)");
  }
  if (newton_iterations < 1 || newton_iterations > 100)
    return bad("newton_iterations must be in 1..100");
  if (settle_newton_iterations < 1 || settle_newton_iterations > 100)
    return bad("settle_newton_iterations must be in 1..100");
  if (settle_newton_max_iterations < settle_newton_iterations || settle_newton_max_iterations > 100)
    return bad("settle_newton_max_iterations must be in settle_newton_iterations..100");
  if (!(static_tolerance > 0 && static_tolerance < 1))
    return bad("static_tolerance must be in (0, 1) (a fraction of the pressure load)");
  if (!(static_step_mm >= 0 && static_step_mm <= 1))
    return bad("static_step_mm must be in [0, 1] mm");
  if (!(static_start_mm >= 0 && static_start_mm <= 10))
    return bad("static_start_mm must be in [0, 10] mm (0: Newton from the closure's end)");
  if (static_max_iterations < 1 || static_max_iterations > 1000)
    return bad("static_max_iterations must be in 1..1000");
  if (!(newton_tolerance > 0)) return bad("newton_tolerance must be positive");
  if (orifice_refine < 0 || orifice_refine > 8) return bad("orifice_refine must be in 0..8");
  if (max_step_halvings < 0 || max_step_halvings > 10)
    return bad("max_step_halvings must be in 0..10");
  if (threads < 1 || threads > 2) return bad("threads must be 1 or 2");
  return true;
}

std::string ClosureSummary::brief_report() const {
  std::ostringstream os;
  os << (converged() ? "closure simulated"
                     : std::string("closure FAILED (") + outcome_name(outcome) + "): " + reason)
     << "; " << steps << " steps (" << halvings << " halvings, " << rejected << " redone smaller, "
     << crossings << " crossings caught, " << newton_iterations << " Newton iterations), " << dofs
     << " dofs, " << elements << " elements; " << wall_s << " s (assembly " << assembly_s
     << ", solve " << solve_s << " of which factorizing " << factorize_s << " (analysis "
     << analyze_s << ") and preconditioning " << precondition_s << ", contact " << contact_s
     << ", other " << other_s << " of which the orifice " << orifice_s
     << "); linear solver: " << factorizations << " factorizations, " << analyses << " analyses ("
     << orderings_reused << " reusing an ordering), " << pcg_iterations << " PCG iterations, "
     << preconditioner_applications << " preconditioner applications, " << warm_starts
     << " warm starts (" << warm_accepted << " answered by the guesses alone), "
     << unconverged_solves << " unconverged, " << double_fallbacks
     << " single-precision factorizations redone in double; contact: " << contacts
     << " pairs at the end (max " << max_contacts << ", closest " << min_contact_distance_mm
     << " mm), " << contact_searches << " searches, " << contact_reused
     << " reused the candidate list; " << interpenetrating_nodes << " of "
     << interpenetration_checked << " surface nodes inside the other leaflet; " << guarded_elements
     << " elements held by the inversion guard";
  if (clip_phase_retries > 0)
    os << "; the clip phase run " << clip_phase_retries + 1 << " times (" << clip_phase_s
       << " s the last)";
  return os.str();
}

ClosureResult simulate_closure(const ValveSequence& seq, const ValveParameters& params,
                               const ClosureOptions& opt) {
  const auto t_start = Clock::now();
  const ClosureScene scene = make_closure_scene(seq, params, opt);  // validates the options
  return simulate_scene(scene, opt, t_start);
}

ClosureResult simulate_closure(const ClosureScene& scene, const ClosureOptions& opt) {
  return simulate_scene(scene, opt, Clock::now());
}

namespace {

ClosureResult simulate_scene(const ClosureScene& scene, const ClosureOptions& opt,
                             Clock::time_point t_start) {
  ClosureOptions o = opt;
  for (int retry = 0;; ++retry) {
    bool clip_phase_failed = false;
    ClosureResult r = simulate_once(scene, o, t_start, &clip_phase_failed);
    r.summary.clip_phase_retries = retry;
    if (!clip_phase_failed || retry >= opt.clip_phase_retries) {
      if (retry > 0 && !r.summary.converged())
        r.summary.reason += " (the clip phase run " + std::to_string(retry + 1) + " times, up to " +
                            std::to_string(o.clip_closing_s) + " s long)";
      return r;
    }
    o.clip_closing_s *= 2.0;  // the arms closing slower
  }
}

ClosureResult simulate_once(const ClosureScene& scene, const ClosureOptions& opt,
                            Clock::time_point t_start, bool* clip_phase_failed) {
  ClosureIntegrator integrator(scene, opt);
  ClosureResult result;
  ValveState state = integrator.initial_state();
  const double T = scene.duration();
  int steps = 0, halvings_total = 0, rejected = 0, settle_steps = 0, settle_iterations = 0;
  double settle_s = 0.0, last_motion_mm = 0.0, orifice_s = 0.0;
  std::string static_failure;
  auto finish = [&](Outcome outcome, std::string reason) {
    result.positions = state.x;
    integrator.finish(&result);
    ClosureSummary& sum = result.summary;
    sum.outcome = outcome;
    sum.reason = std::move(reason);
    sum.steps = steps;
    sum.halvings = halvings_total;
    sum.rejected = rejected;
    sum.settle_steps = settle_steps;
    sum.settle_s = settle_s;
    sum.settle_newton_iterations = settle_iterations;
    sum.last_step_motion_mm = last_motion_mm;
    sum.orifice_s = orifice_s;
    sum.static_failure = static_failure;
    sum.clip_phase_s = integrator.clip_phase_s();
    sum.wall_s = seconds_since(t_start);
    sum.other_s = sum.wall_s - sum.assembly_s - sum.solve_s - sum.contact_s;
  };
  // One step of h from t, halved (h and halvings updated) up to max_step_halvings times while
  // it fails; the outcome of the last try.
  auto step_halving = [&](double t, double* h, int* halvings) {
    StepOutcome o;
    while (!(o = integrator.step(t, *h, &state)).ok() && *halvings < opt.max_step_halvings) {
      ++*halvings;
      ++halvings_total;
      *h *= 0.5;
    }
    return o;
  };

  double tau = -integrator.clip_phase_s();
  if (tau >= 0.0) result.samples.push_back(integrator.sample(0.0, state));
  // Fixed steps of dt (the paper's scheme), or error-controlled steps from dt up to max_dt.
  const StepSizeControl control(opt.dt, opt.max_dt, opt.step_error_mm);
  // Recorded states fall every record_every x dt of the closure, whatever the step sizes.
  const double record_interval = opt.record_every > 0 ? opt.record_every * opt.dt : 0.0;
  double next_record = record_interval;
  double h_next = opt.dt;
  while (tau < T - 1e-12) {
    // Steps land on t = 0, where the clip phase ends and the closure is first recorded.
    double h = tau < 0.0 ? std::min(opt.dt, -tau) : std::min(h_next, T - tau);
    if (control.adaptive() && tau >= 0.0 && record_interval > 0.0 && next_record < T - 1e-12)
      h = std::min(h, next_record - tau);
    int halvings = 0;
    const ValveState before = control.adaptive() ? state : ValveState{};
    if (const StepOutcome o = step_halving(tau, &h, &halvings); !o.ok()) {
      result.samples.push_back(integrator.sample(std::max(tau, 0.0), state));
      *clip_phase_failed = tau < 0.0;
      finish(o.outcome, o.message + " at t = " + std::to_string(tau) + " s" +
                            (tau < 0 ? " (clip phase)" : "") + " (after " +
                            std::to_string(halvings) + " step halvings)");
      return result;
    }
    if (control.adaptive() && tau >= 0.0) {
      const double error = integrator.local_error(before, state, h);
      if (!control.accept(h, error)) {
        state = before;  // redo the step smaller
        ++rejected;
        h_next = control.next(h, error);
        continue;
      }
      h_next = halvings > 0 ? std::max(h, opt.dt) : control.next(h, error);
    }
    const bool clip_phase_ends = tau < 0.0 && tau + h >= -1e-12;
    tau += h;
    ++steps;
    if (clip_phase_ends) {
      tau = 0.0;
      result.samples.push_back(integrator.sample(0.0, state));
      for (int c = 0; c < integrator.num_clips(); ++c)
        result.clip_gap_clipped_mm.push_back(integrator.clip_gap(c, state.x));
      continue;
    }
    if (tau < 0.0) continue;
    if (opt.progress) opt.progress(tau, T);
    if (record_interval > 0.0 && tau >= next_record - 1e-9 && tau < T - 1e-12) {
      result.samples.push_back(integrator.sample(tau, state));
      while (next_record <= tau + 1e-9) next_record += record_interval;
    }
  }
  // Settling: the load held, steps doubling from dt, until a full-size step moves the valve by
  // less than `until_mm`. Implicit Euler's large steps are damped Newton steps toward the
  // equilibrium. Returns false (the result finished as failed) when a step fails.
  auto settle = [&](double until_mm) {
    integrator.disable_friction();
    // A second settling (after a failed static solve) keeps the count the first one raised.
    settle_iterations = std::max(settle_iterations, opt.settle_newton_iterations);
    integrator.set_newton_iterations(settle_iterations);
    // Once raised, as many as a step needs: until a correction moves no node by a quarter of
    // the motion that counts as rest.
    if (settle_iterations > opt.settle_newton_iterations)
      integrator.set_newton_motion_tolerance(kSettleCorrectionShare * until_mm);
    double h = opt.dt;
    ValveState two_before;  // the state before the last full-size step, if the last was one
    bool have_two_before = false;
    while (settle_s < opt.settle_max_s - 1e-12) {
      ValveState before = state;
      int halvings = 0;
      h = std::min(h, opt.settle_max_s - settle_s);
      if (const StepOutcome o = step_halving(T + settle_s, &h, &halvings); !o.ok()) {
        result.samples.push_back(integrator.sample(T, state));
        finish(o.outcome, o.message + " while settling, " + std::to_string(settle_s) +
                              " s after the closure (after " + std::to_string(halvings) +
                              " step halvings)");
        return false;
      }
      settle_s += h;
      ++steps;
      ++settle_steps;
      last_motion_mm = integrator.largest_motion(before, state);
      // At rest: a full-size step (a small one moves little even while the valve creeps).
      const double h_max = std::max(opt.settle_max_dt, opt.dt);
      const bool full_size = h >= h_max - 1e-12;
      if (full_size && last_motion_mm < until_mm) break;
      // A two-step cycle: the iterations stop short of the step's solution, alternately on
      // either side of it, and the valve flips between two states instead of coming to rest.
      if (full_size && have_two_before && settle_iterations < opt.settle_newton_max_iterations &&
          integrator.largest_motion(two_before, state) < 0.5 * last_motion_mm) {
        settle_iterations = std::min(2 * settle_iterations, opt.settle_newton_max_iterations);
        integrator.set_newton_iterations(settle_iterations);
        integrator.set_newton_motion_tolerance(kSettleCorrectionShare * until_mm);
      }
      have_two_before = full_size;
      if (full_size) two_before = std::move(before);
      if (halvings == 0) h = std::min(2.0 * h, h_max);
    }
    return true;
  };
  // Or a static solve (Newton on the equilibrium under the held load), from the closure's end
  // or, with static_start_mm, after settling to that motion per step; should it fail,
  // settling, when on, takes over from where it stopped (the summary says why).
  bool at_rest = false;
  if (opt.static_rest) {
    if (opt.static_start_mm > 0 && !settle(opt.static_start_mm)) return result;
    const StepOutcome o = integrator.solve_static(T, &state);
    at_rest = o.ok();
    if (!o.ok()) {
      static_failure = o.message;
      if (!(opt.settle_mm > 0)) {
        result.samples.push_back(integrator.sample(T, state));
        finish(o.outcome, o.message + " (static solve after the closure)");
        return result;
      }
    }
  }
  if (opt.settle_mm > 0 && !at_rest && !settle(opt.settle_mm)) return result;
  result.samples.push_back(integrator.sample(tau, state));
  for (int c = 0; c < integrator.num_clips(); ++c)
    result.clip_gap_end_mm.push_back(integrator.clip_gap(c, state.x));
  if (opt.orifice_refine > 0 && result.samples.back().la_surface.points().allFinite()) {
    const auto t_orifice = Clock::now();
    std::tie(result.orifice_surface, result.orifice_lv_surface) =
        integrator.leaflet_surfaces(state, opt.orifice_refine);
    OrificeOptions oo;
    oo.seal_mm = orifice_seal_mm(opt.contact);
    for (const ClipGrasp& g : integrator.grasps())
      if (g.line_end > g.line_begin) oo.blocked.emplace_back(g.line_begin, g.line_end);
    result.orifice =
        measure_regurgitant_orifice(result.orifice_surface, oo, &result.orifice_lv_surface);
    orifice_s = seconds_since(t_orifice);
  }
  finish(Outcome::kConverged, "");
  return result;
}

}  // namespace

double orifice_seal_mm(const SelfContactOptions& contact) { return contact.alarm_mm; }

double stress_quantile_kpa(const ClosureResult& r, const std::vector<int>& elements, double q) {
  std::vector<double> v;
  for (int e : elements) {
    if (e >= 0 && e < r.element_stress_mpa.size()) v.push_back(1000.0 * r.element_stress_mpa[e]);
  }
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const double pos = std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1);
  const size_t i = static_cast<size_t>(std::floor(pos));
  const double f = pos - static_cast<double>(i);
  return i + 1 < v.size() ? (1.0 - f) * v[i] + f * v[i + 1] : v[i];
}

SimulationRecord make_simulation_record(const ClosureResult& r, const ClosureOptions& o,
                                        const ValveParameters& p) {
  SimulationRecord rec;
  rec.options = describe_options(o);
  rec.parameters = p;
  const ClosureSummary& s = r.summary;
  rec.status = s.converged() ? "converged" : "failed";
  rec.reason = s.reason;
  rec.outcome = outcome_name(s.outcome);
  rec.summary = {{"steps", s.steps},
                 {"halvings", s.halvings},
                 {"rejected_steps", s.rejected},
                 {"crossings", s.crossings},
                 {"settle_steps", s.settle_steps},
                 {"settle_s", s.settle_s},
                 {"settle_newton_iterations", s.settle_newton_iterations},
                 {"clip_phase_s", s.clip_phase_s},
                 {"clip_phase_retries", s.clip_phase_retries},
                 {"last_step_motion_mm", s.last_step_motion_mm},
                 {"newton_iterations", s.newton_iterations},
                 {"static_iterations", s.static_iterations},
                 {"static_residual_n", s.static_residual_n},
                 {"static_relative_residual", s.static_relative_residual},
                 {"static_s", s.static_s},
                 {"static_step_mm", s.static_step_mm},
                 {"static_converged", o.static_rest && s.static_failure.empty() ? 1 : 0},
                 {"dofs", s.dofs},
                 {"elements", s.elements},
                 {"wall_s", s.wall_s},
                 {"assembly_s", s.assembly_s},
                 {"solve_s", s.solve_s},
                 {"factorize_s", s.factorize_s},
                 {"precondition_s", s.precondition_s},
                 {"analyze_s", s.analyze_s},
                 {"contact_s", s.contact_s},
                 {"other_s", s.other_s},
                 {"contacts", s.contacts},
                 {"max_contacts", s.max_contacts},
                 {"contact_searches", s.contact_searches},
                 {"min_contact_distance_mm", s.min_contact_distance_mm},
                 {"factorizations", s.factorizations},
                 {"pcg_iterations", s.pcg_iterations},
                 {"preconditioner_applications", s.preconditioner_applications},
                 {"warm_starts", s.warm_starts},
                 {"warm_accepted", s.warm_accepted},
                 {"orderings_reused", s.orderings_reused},
                 {"unconverged_solves", s.unconverged_solves},
                 {"double_fallbacks", s.double_fallbacks},
                 {"final_update_norm", s.final_update_norm},
                 {"interpenetrating_nodes", s.interpenetrating_nodes},
                 {"guarded_elements", s.guarded_elements},
                 {"interpenetration_checked", s.interpenetration_checked},
                 {"orifice_s", s.orifice_s}};
  if (o.static_rest) {
    rec.static_residual_n = s.static_history;
    rec.static_failure = s.static_failure;
  }
  for (const ClosureSample& c : r.samples) {
    rec.time_s.push_back(c.time_s);
    rec.observed_time_s.push_back(c.observed_time_s);
    rec.anterior_tip_mm.push_back(c.anterior_tip_mm);
    rec.posterior_tip_mm.push_back(c.posterior_tip_mm);
    rec.orifice_area_mm2.push_back(c.orifice_area_mm2);
    rec.annulus_area_mm2.push_back(c.annulus_area_mm2);
    rec.la_surface.push_back(c.la_surface);
  }
  rec.mesh = r.rest_mesh;
  const Eigen::Index N = r.rest_mesh.V.rows();
  rec.final_positions.resize(N, 3);
  for (Eigen::Index i = 0; i < N; ++i)
    rec.final_positions.row(i) = r.positions.segment<3>(3 * i).transpose();
  rec.element_strain = r.element_strain;
  rec.element_stress_mpa = r.element_stress_mpa;
  rec.orifice = r.orifice;
  if (r.orifice) {
    rec.orifice_surface = r.orifice_surface;
    rec.orifice_lv_surface = r.orifice_lv_surface;
  }
  return rec;
}

}  // namespace mvtwin::forward
