#include "mvtwin/studies/robustness_study.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <mutex>

#include "mvtwin/core/error.h"
#include "mvtwin/core/outcome.h"
#include "mvtwin/core/rng.h"
#include "mvtwin/core/table_file.h"
#include "mvtwin/core/units.h"
#include "mvtwin/core/version.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/studies/plot.h"
#include "mvtwin/studies/report.h"
#include "study_util.h"

namespace mvtwin::studies {
namespace fs = std::filesystem;
using nlohmann::json;

forward::ClosureOptions RobustnessStudyOptions::coarse_model() {
  forward::ClosureOptions m;
  m.model.ures = 20;
  m.model.vres = 10;
  return m;
}

bool RobustnessStudyOptions::is_valid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (out.empty()) return fail("robustness study: no output folder (--out)");
  if (runs < 1 || runs > 1000000) return fail("robustness study: runs must be 1 to 1000000");
  if (jobs < 1 || jobs > 256) return fail("robustness study: jobs must be 1 to 256");
  std::string e;
  if (!model.is_valid(&e)) return fail("robustness study: " + e);
  return true;
}

RobustnessStudyOptions RobustnessStudyOptions::quick() {
  RobustnessStudyOptions o;
  o.runs = 12;
  o.model.model.ures = 12;
  o.model.model.vres = 8;
  return o;
}

json RobustnessStudyOptions::config() const {
  json m = detail::describe(model);
  m.erase("dt");  // drawn per case
  // Not the number of runs: case i does not depend on it, so a larger --runs extends a study.
  return {{"model", m}, {"seed", seed}, {"virtual_patient_edition", kVirtualPatientEdition}};
}

namespace {

struct Drawn {
  Patient patient;
  ValveParameters parameters;
  forward::ClosureOptions options;
  RobustnessCase row;
};

/// Case i: patient i of the cohort `seed` and its own generator for the abuse.
Drawn draw_case(const RobustnessStudyOptions& o, int i) {
  Drawn c;
  const CohortMember m = cohort_member(o.seed, i);
  c.patient = make_cohort_patient(o.seed, i);
  c.row.index = i;
  c.row.patient_seed = m.seed;
  Rng rng(m.seed ^ 0x5EEDABu);
  Patient& p = c.patient;
  ValveParameters& par = c.parameters;
  par = p.truth->parameters;
  for (double& f : par.restlength_factor) f = rng.uniform(0.5, 1.5);
  par.marginal_stiffness_scale = std::exp(rng.uniform(std::log(0.2), std::log(5.0)));
  par.basal_stiffness_scale = std::exp(rng.uniform(std::log(0.2), std::log(5.0)));
  par.al_modulus_scale = std::exp(rng.uniform(std::log(0.2), std::log(5.0)));
  par.pl_modulus_scale = std::exp(rng.uniform(std::log(0.2), std::log(5.0)));
  par.peak_pressure_mpa = units::mmhg_to_mpa(rng.uniform(0.0, 200.0));
  c.options = o.model;
  c.options.progress = nullptr;
  c.options.dt = std::exp(rng.uniform(std::log(0.001), std::log(0.1)));
  const double a = rng.uniform();
  c.row.anatomy = "clean";
  ValveFrame& ed = p.sequence.frames[p.sequence.end_diastole];
  if (a < 0.17) {
    c.row.anatomy = "noisy";
    const double sd = rng.uniform(0.3, 1.0);
    for (int f = 0; f < p.sequence.num_frames(); ++f) {
      if (!p.sequence.frames[f].la_surface) continue;
      auto& P = p.sequence.frames[f].la_surface->points();
      for (Eigen::Index k = p.sequence.ures; k < P.rows(); ++k)
        for (int d = 0; d < 3; ++d) P(k, d) += rng.normal(0.0, sd);
    }
  } else if (a < 0.33) {
    c.row.anatomy = "degenerate";
    // Collapse two neighbouring columns onto one another.
    auto& P = ed.la_surface->points();
    const int U = ed.la_surface->ures(), u = rng.uniform_int(1, U - 2);
    for (int v = 1; v < ed.la_surface->vres(); ++v) P.row(v * U + u + 1) = P.row(v * U + u);
  }
  c.row.dt = c.options.dt;
  c.row.peak_pressure_mmhg = units::mpa_to_mmhg(par.peak_pressure_mpa);
  return c;
}

/// Runs one case; never throws.
RobustnessCase run_case(const RobustnessStudyOptions& o, int i) {
  RobustnessCase row;
  row.index = i;
  try {
    Drawn c = draw_case(o, i);
    row = c.row;
    const forward::ClosureResult r =
        forward::simulate_closure(c.patient.sequence, c.parameters, c.options);
    row.wall_s = r.summary.wall_s;
    bool finite = r.positions.allFinite();
    for (const auto& s : r.samples) finite = finite && s.la_surface.points().allFinite();
    if (!finite) {
      row.outcome = "nonfinite_output";
    } else if (r.summary.converged()) {
      row.outcome = "converged";
    } else {
      row.outcome = "clean_failure";
      row.reason = r.summary.reason;
      row.failure_kind = outcome_name(r.summary.outcome);
    }
  } catch (const Error& e) {
    row.outcome = "clean_failure";
    row.reason = e.what();
    row.failure_kind = outcome_name(Outcome::kInvalidInput);
  } catch (const std::exception& e) {
    row.outcome = "crash";
    row.reason = e.what();
  } catch (...) {
    row.outcome = "crash";
    row.reason = "unknown exception";
  }
  return row;
}

json case_json(const RobustnessCase& c) {
  return {{"index", c.index},
          {"patient_seed", c.patient_seed},
          {"anatomy", c.anatomy},
          {"dt", c.dt},
          {"peak_pressure_mmhg", c.peak_pressure_mmhg},
          {"outcome", c.outcome},
          {"reason", c.reason},
          {"failure_kind", c.failure_kind},
          {"wall_s", c.wall_s}};
}

RobustnessCase case_from_json(const json& j) {
  RobustnessCase c;
  c.index = j.at("index");
  c.patient_seed = j.value("patient_seed", std::uint64_t{0});
  c.anatomy = j.value("anatomy", "");
  c.dt = j.value("dt", 0.0);
  c.peak_pressure_mmhg = j.value("peak_pressure_mmhg", 0.0);
  c.outcome = j.at("outcome");
  c.reason = j.value("reason", "");
  c.failure_kind = j.value("failure_kind", "");
  c.wall_s = j.value("wall_s", 0.0);
  return c;
}

void write_outputs(const RobustnessStudyOptions& o, const RobustnessStudyResult& r,
                   const StudyFolder& f);

}  // namespace

RobustnessStudyResult run_robustness_study(const RobustnessStudyOptions& o, WorkPool& pool) {
  std::string err;
  if (!o.is_valid(&err)) throw Error(err);
  const auto t0 = std::chrono::steady_clock::now();
  const std::unique_ptr<StudyFolder> folder =
      open_study_folder(pool, o.out, "robustness", o.config());

  std::mutex m;
  std::atomic<int> done{0};
  const auto out = pool.map(o.runs, o.jobs, [&](int i) -> std::string {
    const std::string name = "case_" + std::to_string(i);
    if (auto rec = folder->record(name)) {
      ++done;
      if (o.progress) {
        std::lock_guard<std::mutex> lock(m);
        o.progress({"simulate", done, o.runs, name + ": done before (resumed)"});
      }
      return rec->dump();
    }
    const RobustnessCase c = run_case(o, i);
    const json j = case_json(c);
    folder->save_record(name, j);
    ++done;
    if (o.progress) {
      std::lock_guard<std::mutex> lock(m);
      o.progress({"simulate", done, o.runs,
                  name + " (" + c.anatomy + ", dt " + number(c.dt, 4) + " s): " + c.outcome +
                      (c.reason.empty() ? "" : ": " + c.reason)});
    }
    return j.dump();
  });
  RobustnessStudyResult res;
  for (const auto& s : out) {
    res.cases.push_back(case_from_json(json::parse(s)));
    const std::string& k = res.cases.back().outcome;
    res.converged += k == "converged";
    res.clean_failures += k == "clean_failure";
    res.crashes += k == "crash";
    res.nonfinite += k == "nonfinite_output";
  }
  res.workers = pool.describe();
  res.wall_s = detail::seconds_since(t0);
  if (pool.is_root()) write_outputs(o, res, *folder);
  pool.barrier();
  return res;
}

namespace {

void write_outputs(const RobustnessStudyOptions& o, const RobustnessStudyResult& r,
                   const StudyFolder& f) {
  std::map<std::string, int> kinds;
  json cases = json::array();
  for (const auto& c : r.cases) {
    cases.push_back(case_json(c));
    if (!c.failure_kind.empty()) ++kinds[c.failure_kind];
  }
  json prov = detail::provenance(o.command, r.workers, r.wall_s);
  prov["seed"] = o.seed;
  write_json(f.path("study.json"), {{"format", "mvtwin-robustness-study"},
                                    {"study", "robustness"},
                                    {"synthetic", true},
                                    {"config", o.config()},
                                    {"provenance", prov},
                                    {"runs", r.cases.size()},
                                    {"converged", r.converged},
                                    {"clean_failures", r.clean_failures},
                                    {"crashes", r.crashes},
                                    {"nonfinite_outputs", r.nonfinite},
                                    {"clean_failure_kinds", kinds},
                                    {"cases", cases}});
  TableFile t;
  t.format = "mvtwin-robustness-study";
  t.attributes = {{"mvtwin_version", kVersion},
                  {"command", o.command},
                  {"synthetic", "1"},
                  {"config", o.config().dump()}};
  TableColumn anatomy{"anatomy", "", {}, {}}, outcome{"outcome", "", {}, {}},
      kind{"failure_kind", "", {}, {}}, reason{"reason", "", {}, {}}, dt{"dt", "s", {}, {}},
      pressure{"peak_pressure_mmhg", "mmHg", {}, {}}, wall{"wall_s", "s", {}, {}},
      seed{"patient_seed", "", {}, {}};
  for (const auto& c : r.cases) {
    anatomy.strings.push_back(c.anatomy.empty() ? "-" : c.anatomy);
    outcome.strings.push_back(c.outcome);
    kind.strings.push_back(c.failure_kind.empty() ? "-" : c.failure_kind);
    reason.strings.push_back(c.reason.empty() ? "-" : c.reason);
    dt.numbers.push_back(c.dt);
    pressure.numbers.push_back(c.peak_pressure_mmhg);
    wall.numbers.push_back(c.wall_s);
    seed.numbers.push_back(static_cast<double>(c.patient_seed));
  }
  t.columns = {anatomy, outcome, kind, reason, dt, pressure, wall, seed};
  write_table_file(f.path("study.h5"), t);

  Report rep("Robustness study: the simulator under abuse");
  rep.paragraph(
      std::to_string(r.cases.size()) + " SYNTHETIC cases (cohort seed " + std::to_string(o.seed) +
      ", pathologies in turn), each with extreme inputs: chordae rest-length factors 0.5-1.5, "
      "chordae stiffness and leaflet moduli x0.2-5 (log-uniform), peak pressure 0-200 mmHg, "
      "time step 0.001-0.1 s (log-uniform), and in a sixth of the cases leaflets with 0.3-1 mm "
      "noise, in another sixth two collapsed grid columns. Model " +
      std::to_string(o.model.model.ures) + " x " + std::to_string(o.model.model.vres) + ", " +
      std::to_string(o.model.model.layers) +
      " layer(s). A clean failure is a status with a reason (or a named input error); a crash is "
      "any other exception; non-finite output is NaN or infinity in a result that claims "
      "success. The paper reports no such test; it notes that leaflets interpenetrate at dt = "
      "0.1 s (" +
      std::string(kPaperCitation) + ", Sec. 4.1).");
  rep.heading("Outcomes");
  std::vector<std::vector<std::string>> rows;
  for (const char* a : {"clean", "noisy", "degenerate", "all"}) {
    int n = 0, conv = 0, clean = 0, crash = 0, nonf = 0;
    for (const auto& c : r.cases) {
      if (std::string(a) != "all" && c.anatomy != a) continue;
      ++n;
      conv += c.outcome == "converged";
      clean += c.outcome == "clean_failure";
      crash += c.outcome == "crash";
      nonf += c.outcome == "nonfinite_output";
    }
    rows.push_back({a, std::to_string(n), std::to_string(conv), std::to_string(clean),
                    std::to_string(crash), std::to_string(nonf)});
  }
  rep.table({"anatomy", "cases", "converged", "clean failures", "crashes", "non-finite outputs"},
            rows);
  rows.clear();
  for (const auto& [k, n] : kinds) rows.push_back({k, std::to_string(n)});
  if (!rows.empty()) {
    rep.heading("Clean failures by kind");
    rep.table({"kind", "cases"}, rows);
  }
  {
    // Outcome against the time step, where the failures concentrate.
    Plot fig;
    fig.title = "Outcome against the time step";
    fig.x_label = "time step, s";
    fig.y_label = "peak pressure, mmHg";
    fig.log_x = true;
    std::map<std::string, PlotSeries> by;
    for (const auto& c : r.cases) {
      if (c.dt <= 0) continue;
      const std::string key =
          c.outcome == "clean_failure" ? "clean failure: " + c.failure_kind : c.outcome;
      auto& s = by[key];
      s.name = key;
      s.line = false;
      s.x.push_back(c.dt);
      s.y.push_back(c.peak_pressure_mmhg);
    }
    // Converged cases first: the failures are drawn over them, not hidden under them.
    if (by.count("converged")) fig.series.push_back(by["converged"]);
    for (auto& [k, s] : by)
      if (k != "converged") fig.series.push_back(s);
    if (!fig.series.empty()) {
      fig.write_png(f.path("outcomes.png"));
      rep.figure("outcomes.png",
                 "Every case by its time step and peak pressure, marked by outcome (failures on "
                 "top).");
    }
  }
  {
    // The share of each outcome per decade-third of the time step: readable at any number of
    // cases, where the scatter above saturates.
    constexpr int kBins = 6;
    double lo = 0, hi = 0;
    bool any = false;
    for (const auto& c : r.cases) {
      if (c.dt <= 0) continue;
      const double l = std::log10(c.dt);
      lo = any ? std::min(lo, l) : l;
      hi = any ? std::max(hi, l) : l;
      any = true;
    }
    if (any && hi > lo) {
      std::map<std::string, std::vector<double>> count;
      std::vector<double> total(kBins, 0.0);
      for (const auto& c : r.cases) {
        if (c.dt <= 0) continue;
        const int b =
            std::min(kBins - 1, static_cast<int>((std::log10(c.dt) - lo) / (hi - lo) * kBins));
        const std::string key = c.outcome == "clean_failure" ? c.failure_kind : c.outcome;
        if (key == "converged") continue;
        count[key].resize(kBins, 0.0);
        count[key][b] += 1;
        total[b] += 1;
      }
      for (const auto& c : r.cases)
        if (c.dt > 0 && c.outcome == "converged")
          total[std::min(kBins - 1,
                         static_cast<int>((std::log10(c.dt) - lo) / (hi - lo) * kBins))] += 1;
      Plot fig;
      fig.title = "Failures against the time step";
      fig.x_label = "time step, s (bin centre)";
      fig.y_label = "cases in the bin, %";
      fig.log_x = true;
      for (const auto& [k, n] : count) {
        PlotSeries s;
        s.name = k;
        for (int b = 0; b < kBins; ++b) {
          if (total[b] == 0) continue;
          s.x.push_back(std::pow(10.0, lo + (b + 0.5) * (hi - lo) / kBins));
          s.y.push_back(100.0 * n[b] / total[b]);
        }
        fig.series.push_back(s);
      }
      if (!fig.series.empty()) {
        fig.write_png(f.path("failure_rates.png"));
        rep.figure("failure_rates.png",
                   "Share of the cases in each time-step bin that failed, by typed reason "
                   "(crashes and non-finite outputs would be their own lines).");
      }
    }
  }
  rep.how_made(o.command, r.workers, r.wall_s);
  rep.write(f.dir());
}

}  // namespace

}  // namespace mvtwin::studies
