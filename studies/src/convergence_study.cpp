#include "mvtwin/studies/convergence_study.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <sstream>

#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/point_to_mesh_distance.h"
#include "mvtwin/core/table_file.h"
#include "mvtwin/core/version.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/studies/plot.h"
#include "mvtwin/studies/report.h"
#include "study_util.h"

namespace mvtwin::studies {
namespace fs = std::filesystem;
using detail::kNaN;
using nlohmann::json;

namespace {

std::string text(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

template <class T>
bool strictly_increasing(const std::vector<T>& v) {
  for (std::size_t i = 1; i < v.size(); ++i)
    if (!(v[i] > v[i - 1])) return false;
  return true;
}

}  // namespace

bool ConvergenceStudyOptions::is_valid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (out.empty()) return fail("convergence study: no output folder (--out)");
  if (patient < 0) return fail("convergence study: negative patient index");
  if (jobs < 1 || jobs > 256) return fail("convergence study: jobs must be 1 to 256");
  if (ures.size() < 2 || vres.size() < 2 || layers.size() < 2 || dt.size() < 2)
    return fail(
        "convergence study: every series needs at least two values (the last is its "
        "reference)");
  if (!strictly_increasing(ures) || !strictly_increasing(vres) || !strictly_increasing(layers))
    return fail("convergence study: ures, vres and layers must increase (coarse to fine)");
  for (std::size_t i = 1; i < dt.size(); ++i)
    if (!(dt[i] < dt[i - 1])) return fail("convergence study: dt must decrease (coarse to fine)");
  std::string e;
  if (!model.is_valid(&e)) return fail("convergence study: " + e);
  try {
    forward::ClosureOptions m = model;
    for (const auto& a : pair) forward::apply_option(a, &m);
    if (!m.is_valid(&e)) return fail("convergence study: the paired run: " + e);
  } catch (const std::exception& x) {
    return fail(std::string("convergence study: the paired run: ") + x.what());
  }
  // Every run's model must be valid too: check the extremes of each series.
  for (const int u : {ures.front(), ures.back()}) {
    forward::ClosureOptions m = model;
    m.model.ures = u;
    if (!m.is_valid(&e)) return fail("convergence study: ures " + std::to_string(u) + ": " + e);
  }
  for (const int v : {vres.front(), vres.back()}) {
    forward::ClosureOptions m = model;
    m.model.vres = v;
    if (!m.is_valid(&e)) return fail("convergence study: vres " + std::to_string(v) + ": " + e);
  }
  for (const int l : {layers.front(), layers.back()}) {
    forward::ClosureOptions m = model;
    m.model.layers = l;
    if (!m.is_valid(&e)) return fail("convergence study: layers " + std::to_string(l) + ": " + e);
  }
  for (const double d : {dt.front(), dt.back()}) {
    forward::ClosureOptions m = model;
    m.dt = d;
    if (!m.is_valid(&e)) return fail("convergence study: dt " + text(d) + ": " + e);
  }
  return true;
}

ConvergenceStudyOptions ConvergenceStudyOptions::quick() {
  ConvergenceStudyOptions o;
  o.model.model.ures = 12;
  o.model.model.vres = 8;
  o.model.dt = 0.02;
  o.ures = {12, 16};
  o.vres = {6, 8};
  o.layers = {1, 2};
  o.dt = {0.04, 0.02, 0.01};
  return o;
}

json ConvergenceStudyOptions::config() const {
  json c{{"model", detail::describe(model)},
         {"ures", ures},
         {"vres", vres},
         {"layers", layers},
         {"dt", dt}};
  if (!pair.empty()) c["pair"] = pair;
  if (patient_file.empty())
    c.update({{"seed", seed},
              {"patient", patient},
              {"virtual_patient_edition", kVirtualPatientEdition}});
  else
    c["patient_file"] = fs::absolute(patient_file).lexically_normal().string();
  return c;
}

namespace {

std::vector<ConvergenceRun> convergence_runs(const ConvergenceStudyOptions& o) {
  std::vector<ConvergenceRun> runs;
  auto series = [&](const std::string& factor, const std::vector<std::string>& values) {
    for (std::size_t i = 0; i < values.size(); ++i) {
      ConvergenceRun r;
      r.factor = factor;
      r.value = values[i];
      r.settings = {factor + "=" + values[i]};
      r.reference = i + 1 == values.size();
      runs.push_back(std::move(r));
    }
  };
  auto texts = [](const auto& v) {
    std::vector<std::string> t;
    for (const auto& x : v) t.push_back(text(static_cast<double>(x)));
    return t;
  };
  series("ures", texts(o.ures));
  series("vres", texts(o.vres));
  series("layers", texts(o.layers));
  series("dt", texts(o.dt));
  return runs;
}

/// One distinct model: its options and, once simulated, its end atrial surface.
struct Simulation {
  forward::ClosureOptions options;
  std::string key;  ///< what decides it
  double cost = 0;  ///< a relative estimate, to start the longest first
};

json simulate_one(const Patient& patient, const ValveParameters& parameters,
                  const forward::ClosureOptions& options) {
  json j;
  try {
    const forward::ClosureResult r =
        forward::simulate_closure(patient.sequence, parameters, options);
    const auto& s = r.summary;
    j = {{"status", s.converged() ? "ok" : "failed"},
         {"reason", s.reason},
         {"wall_s", s.wall_s},
         {"steps", s.steps},
         {"dofs", s.dofs},
         {"tets", s.elements}};
    if (options.static_rest) {
      j["static_converged"] = s.static_failure.empty();
      j["static_iterations"] = s.static_iterations;
    }
    if (s.converged()) {
      const LeafletGrid& g = r.samples.back().la_surface;
      std::vector<double> xyz(static_cast<std::size_t>(g.points().rows()) * 3);
      for (Eigen::Index k = 0; k < g.points().rows(); ++k)
        for (int d = 0; d < 3; ++d) xyz[static_cast<std::size_t>(3 * k + d)] = g.points()(k, d);
      j["end_orifice_mm2"] = r.samples.back().orifice_area_mm2;
      j["surface"] = {{"ures", g.ures()}, {"vres", g.vres()}, {"xyz_mm", xyz}};
    }
  } catch (const std::exception& e) {
    j = {{"status", "failed"}, {"reason", e.what()}, {"wall_s", 0.0},
         {"steps", 0},         {"dofs", 0},          {"tets", 0}};
  }
  return j;
}

LeafletGrid surface_of(const json& j) {
  const json& s = j.at("surface");
  const auto xyz = s.at("xyz_mm").get<std::vector<double>>();
  LeafletGrid::Points p(static_cast<Eigen::Index>(xyz.size() / 3), 3);
  for (Eigen::Index k = 0; k < p.rows(); ++k)
    for (int d = 0; d < 3; ++d) p(k, d) = xyz[static_cast<std::size_t>(3 * k + d)];
  return LeafletGrid(s.at("ures").get<int>(), s.at("vres").get<int>(), std::move(p));
}

void write_outputs(const ConvergenceStudyOptions& o, const ConvergenceStudyResult& r,
                   const StudyFolder& f);

}  // namespace

ConvergenceStudyResult run_convergence_study(const ConvergenceStudyOptions& o, WorkPool& pool) {
  std::string err;
  if (!o.is_valid(&err)) throw Error(err);
  const auto t0 = std::chrono::steady_clock::now();
  const std::unique_ptr<StudyFolder> folder =
      open_study_folder(pool, o.out, "convergence", o.config());

  ValveParameters parameters;
  forward::ClosureOptions base = o.model;
  const Patient patient = detail::study_patient(o.seed, o.patient, o.patient_file, &parameters);
  base.progress = nullptr;
  base.record_every = 0;  // the end state is all the study compares
  // Fixed steps: the dt series measures the scheme at each step size (error-controlled steps
  // would make dt only the smallest step).
  base.step_error_mm = 0.0;

  // The distinct models: the base model is in every series and is simulated once.
  std::vector<ConvergenceRun> runs = convergence_runs(o);
  std::vector<Simulation> sims;
  std::vector<int> sim_of(runs.size());
  for (std::size_t i = 0; i < runs.size(); ++i) {
    forward::ClosureOptions m = base;
    for (const auto& s : runs[i].settings) forward::apply_option(s, &m);
    const std::string key = detail::describe(m).dump();
    auto it =
        std::find_if(sims.begin(), sims.end(), [&](const Simulation& s) { return s.key == key; });
    if (it == sims.end()) {
      const double cost = static_cast<double>(m.model.ures) * m.model.vres * m.model.layers / m.dt;
      sims.push_back({m, key, cost});
      it = sims.end() - 1;
    }
    sim_of[i] = static_cast<int>(it - sims.begin());
  }
  // The paired runs: each distinct model again with o.pair on top.
  std::vector<int> paired_of(sims.size(), -1);
  if (!o.pair.empty()) {
    const std::size_t n_main = sims.size();
    for (std::size_t k = 0; k < n_main; ++k) {
      forward::ClosureOptions m = sims[k].options;
      for (const auto& a : o.pair) forward::apply_option(a, &m);
      sims.push_back({m, detail::describe(m).dump(), sims[k].cost});
      paired_of[k] = static_cast<int>(sims.size() - 1);
    }
  }
  // The longest first, so that no long run starts last (records are named by their model).
  std::vector<int> order(sims.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return sims[static_cast<std::size_t>(a)].cost > sims[static_cast<std::size_t>(b)].cost;
  });
  const std::size_t n_main = paired_of.size();
  auto record_name = [&](int s) {
    const auto& m = sims[static_cast<std::size_t>(s)].options;
    return "run_u" + std::to_string(m.model.ures) + "_v" + std::to_string(m.model.vres) + "_l" +
           std::to_string(m.model.layers) + "_dt" + text(m.dt) +
           (static_cast<std::size_t>(s) >= n_main ? "_paired" : "");
  };

  const int n = static_cast<int>(sims.size());
  std::mutex progress_mutex;
  std::atomic<int> done{0};
  auto report = [&](const std::string& msg) {
    if (!o.progress) return;
    std::lock_guard<std::mutex> lock(progress_mutex);
    o.progress({"simulate", done, n, msg});
  };
  const auto out = pool.map(n, o.jobs, [&](int k) -> std::string {
    const int s = order[static_cast<std::size_t>(k)];
    const std::string name = record_name(s);
    if (auto rec = folder->record(name)) {
      if (rec->value("key", "") == sims[static_cast<std::size_t>(s)].key) {
        ++done;
        report(name + ": done before (resumed)");
        return rec->dump();
      }
    }
    json j = simulate_one(patient, parameters, sims[static_cast<std::size_t>(s)].options);
    j["key"] = sims[static_cast<std::size_t>(s)].key;
    folder->save_record(name, j);
    ++done;
    report(name + (j.at("status") == "ok" ? ": " + number(j.at("wall_s").get<double>(), 1) + " s"
                                          : ": failed: " + j.value("reason", "")));
    return j.dump();
  });
  std::vector<json> sim_json(sims.size());
  for (std::size_t k = 0; k < out.size(); ++k)
    sim_json[static_cast<std::size_t>(order[k])] = json::parse(out[k]);

  ConvergenceStudyResult res;
  res.patient_id = patient.id;
  res.synthetic = patient.synthetic || patient.truth.has_value();
  res.simulations = n;
  // Errors against each series' reference (its last run).
  std::map<std::string, LeafletGrid> reference;
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const json& j = sim_json[static_cast<std::size_t>(sim_of[i])];
    if (runs[i].reference && j.at("status") == "ok") reference[runs[i].factor] = surface_of(j);
  }
  for (std::size_t i = 0; i < runs.size(); ++i) {
    ConvergenceRun& r = runs[i];
    const json& j = sim_json[static_cast<std::size_t>(sim_of[i])];
    const int paired = paired_of[static_cast<std::size_t>(sim_of[i])];
    r.status = j.at("status");
    r.reason = j.value("reason", "");
    r.wall_s = j.value("wall_s", 0.0);
    r.steps = j.value("steps", 0);
    r.dofs = j.value("dofs", 0);
    r.tets = j.value("tets", 0);
    r.end_orifice_mm2 = j.value("end_orifice_mm2", kNaN);
    r.error_mean_mm = r.error_sd_mm = r.error_p95_mm = r.error_max_mm = kNaN;
    const auto ref = reference.find(r.factor);
    if (r.status == "ok" && ref != reference.end()) {
      const DistanceStats e =
          symmetric_surface_distance(surface_of(j).triangulate(), ref->second.triangulate())
              .symmetric;
      r.error_mean_mm = e.mean;
      r.error_sd_mm = e.sd;
      r.error_p95_mm = e.p95;
      r.error_max_mm = e.max;
    }
    if (paired >= 0) {
      const json& q = sim_json[static_cast<std::size_t>(paired)];
      r.paired_status = q.at("status");
      r.paired_reason = q.value("reason", "");
      r.paired_wall_s = q.value("wall_s", 0.0);
      r.paired_steps = q.value("steps", 0);
      r.paired_static_converged = q.value("static_converged", false);
      r.paired_error_mean_mm = r.paired_error_max_mm = r.paired_difference_mm = kNaN;
      if (r.paired_status == "ok") {
        const LeafletGrid end = surface_of(q);
        if (ref != reference.end()) {
          const DistanceStats e =
              symmetric_surface_distance(end.triangulate(), ref->second.triangulate()).symmetric;
          r.paired_error_mean_mm = e.mean;
          r.paired_error_max_mm = e.max;
        }
        if (r.status == "ok")
          r.paired_difference_mm =
              symmetric_surface_distance(end.triangulate(), surface_of(j).triangulate())
                  .symmetric.mean;
      }
    }
  }
  res.runs = std::move(runs);
  res.workers = pool.describe();
  res.wall_s = detail::seconds_since(t0);
  if (pool.is_root()) write_outputs(o, res, *folder);
  pool.barrier();
  return res;
}

namespace {

using detail::nullable;

/// The paper's errors against the finest run of each series (its Sec. 4.1).
std::string paper_error(const std::string& factor, const std::string& value) {
  static const std::map<std::pair<std::string, std::string>, std::string> k = {
      {{"ures", "30"}, "0.48 ± 0.28"},
      {{"ures", "40"}, "0.46 ± 0.25"},
      {{"vres", "10"}, "0.74 ± 0.85"},
      {{"vres", "20"}, "0.31 ± 0.23"},
      {{"dt", "0.001"}, "0.03 ± 0.04 (max 0.21)"},
      {{"dt", "0.01"}, "0.20 ± 0.20 (max 1.84)"},
      {{"dt", "0.1"}, "0.62 ± 0.61 (max 3.50), leaflets interpenetrate"}};
  const auto it = k.find({factor, value});
  return it == k.end() ? "" : it->second;
}

const std::map<std::pair<std::string, std::string>, double> kPaperMeans = {
    {{"ures", "30"}, 0.48},  {{"ures", "40"}, 0.46}, {{"vres", "10"}, 0.74}, {{"vres", "20"}, 0.31},
    {{"dt", "0.001"}, 0.03}, {{"dt", "0.01"}, 0.20}, {{"dt", "0.1"}, 0.62}};

std::string factor_title(const std::string& f) {
  if (f == "ures") return "in-plane resolution (ures)";
  if (f == "vres") return "radial resolution (vres)";
  if (f == "layers") return "layers through the thickness";
  return "time step, s";
}

void write_outputs(const ConvergenceStudyOptions& o, const ConvergenceStudyResult& r,
                   const StudyFolder& f) {
  json runs = json::array();
  for (const auto& k : r.runs)
    runs.push_back({{"factor", k.factor},
                    {"value", k.value},
                    {"settings", k.settings},
                    {"reference", k.reference},
                    {"status", k.status},
                    {"reason", k.reason},
                    {"wall_s", k.wall_s},
                    {"steps", k.steps},
                    {"dofs", k.dofs},
                    {"tets", k.tets},
                    {"end_orifice_mm2", nullable(k.end_orifice_mm2)},
                    {"error_mean_mm", nullable(k.error_mean_mm)},
                    {"error_sd_mm", nullable(k.error_sd_mm)},
                    {"error_p95_mm", nullable(k.error_p95_mm)},
                    {"error_max_mm", nullable(k.error_max_mm)}});
  if (!o.pair.empty()) {
    for (std::size_t i = 0; i < r.runs.size(); ++i) {
      const auto& k = r.runs[i];
      runs[i]["paired"] = {{"settings", o.pair},
                           {"status", k.paired_status},
                           {"reason", k.paired_reason},
                           {"wall_s", k.paired_wall_s},
                           {"steps", k.paired_steps},
                           {"static_converged", k.paired_static_converged},
                           {"error_mean_mm", nullable(k.paired_error_mean_mm)},
                           {"error_max_mm", nullable(k.paired_error_max_mm)},
                           {"difference_mean_mm", nullable(k.paired_difference_mm)}};
    }
  }
  json prov = detail::provenance(o.command, r.workers, r.wall_s);
  prov["seed"] = o.patient_file.empty() ? json(o.seed) : json(nullptr);
  write_json(f.path("study.json"), {{"format", "mvtwin-convergence-study"},
                                    {"study", "convergence"},
                                    {"patient", r.patient_id},
                                    {"synthetic", r.synthetic},
                                    {"config", o.config()},
                                    {"simulations", r.simulations},
                                    {"provenance", prov},
                                    {"runs", runs}});
  TableFile t;
  t.format = "mvtwin-convergence-study";
  t.attributes = {{"mvtwin_version", kVersion},
                  {"command", o.command},
                  {"patient", r.patient_id},
                  {"synthetic", r.synthetic ? "1" : "0"},
                  {"config", o.config().dump()}};
  TableColumn factor{"factor", "", {}, {}}, value{"value", "", {}, {}},
      status{"status", "", {}, {}}, wall{"wall_s", "s", {}, {}}, steps{"steps", "", {}, {}},
      dofs{"dofs", "", {}, {}}, mean{"error_mean_mm", "mm", {}, {}},
      sd{"error_sd_mm", "mm", {}, {}}, p95{"error_p95_mm", "mm", {}, {}},
      mx{"error_max_mm", "mm", {}, {}};
  for (const auto& k : r.runs) {
    factor.strings.push_back(k.factor);
    value.strings.push_back(k.value);
    status.strings.push_back(k.status);
    wall.numbers.push_back(k.wall_s);
    steps.numbers.push_back(k.steps);
    dofs.numbers.push_back(k.dofs);
    mean.numbers.push_back(k.error_mean_mm);
    sd.numbers.push_back(k.error_sd_mm);
    p95.numbers.push_back(k.error_p95_mm);
    mx.numbers.push_back(k.error_max_mm);
  }
  t.columns = {factor, value, status, wall, steps, dofs, mean, sd, p95, mx};
  if (!o.pair.empty()) {
    TableColumn pstatus{"paired_status", "", {}, {}}, pwall{"paired_wall_s", "s", {}, {}},
        pmean{"paired_error_mean_mm", "mm", {}, {}}, pmax{"paired_error_max_mm", "mm", {}, {}},
        pdiff{"paired_difference_mean_mm", "mm", {}, {}};
    for (const auto& k : r.runs) {
      pstatus.strings.push_back(k.paired_status);
      pwall.numbers.push_back(k.paired_wall_s);
      pmean.numbers.push_back(k.paired_error_mean_mm);
      pmax.numbers.push_back(k.paired_error_max_mm);
      pdiff.numbers.push_back(k.paired_difference_mm);
    }
    for (auto* c : {&pstatus, &pwall, &pmean, &pmax, &pdiff}) t.columns.push_back(*c);
  }
  write_table_file(f.path("study.h5"), t);

  Report rep("Convergence study: what each refinement buys");
  rep.paragraph("Compared with " + std::string(kPaperCitation) + " (its Sec. 4.1 and Figs 10-12).");
  rep.paragraph(
      "Patient `" + r.patient_id + "`" +
      (r.synthetic ? " (SYNTHETIC, its hidden parameters)" : "") + "; base model " +
      std::to_string(o.model.model.ures) + " x " + std::to_string(o.model.model.vres) + ", " +
      std::to_string(o.model.model.layers) + " layer(s), dt " + number(o.model.dt, 4) +
      " s. One factor varies at a time; error: the symmetric point-to-mesh distance between the "
      "closed atrial surface of a run and that of the finest run of its series (mean ± SD, 95th "
      "percentile, max). " +
      std::to_string(r.simulations) + " simulations were run (the base model, which is in every " +
      "series, once" + (o.pair.empty() ? "" : "; each model also as its paired run") + ").");
  rep.heading("mvtwin next to the paper");
  std::vector<std::vector<std::string>> rows;
  for (const auto& k : r.runs) {
    const bool ok = k.status == "ok";
    rows.push_back(
        {k.factor, k.value + (k.reference ? " (reference)" : ""), ok ? number(k.wall_s, 1) : "-",
         ok ? std::to_string(k.steps) : "-", ok ? std::to_string(k.dofs) : "-",
         ok ? (k.reference ? "0" : mean_sd(k.error_mean_mm, k.error_sd_mm)) : "failed: " + k.reason,
         ok && !k.reference ? number(k.error_p95_mm) : "-",
         ok && !k.reference ? number(k.error_max_mm) : "-", paper_error(k.factor, k.value)});
  }
  rep.table({"factor", "value", "wall, s", "steps", "dofs", "error, mm", "p95, mm", "max, mm",
             "paper, mm"},
            rows);
  if (!o.pair.empty()) {
    std::string added;
    for (const auto& a : o.pair) added += (added.empty() ? "`" : ", `") + a + "`";
    rep.heading("Paired: each model again with " + added);
    rep.paragraph(
        "The same model with these settings on top (by default the closed valve at rest by the "
        "static solve instead of settling), run beside it and measured against the same "
        "references (each series' finest run as above). \"apart\": the mean symmetric distance "
        "between the two end surfaces of one model. A static solve that did not converge "
        "hands over to settling (marked *).");
    std::vector<std::vector<std::string>> prow;
    for (const auto& k : r.runs) {
      const bool ok = k.status == "ok", pok = k.paired_status == "ok";
      prow.push_back(
          {k.factor, k.value + (k.reference ? " (reference)" : ""), ok ? number(k.wall_s, 2) : "-",
           pok ? number(k.paired_wall_s, 2) + (k.paired_static_converged ? "" : " *")
               : "failed: " + k.paired_reason,
           ok ? number(k.error_mean_mm, 3) : "-", pok ? number(k.paired_error_mean_mm, 3) : "-",
           ok ? number(k.error_max_mm, 3) : "-", pok ? number(k.paired_error_max_mm, 3) : "-",
           ok && pok ? number(k.paired_difference_mm, 3) : "-"});
    }
    rep.table({"factor", "value", "wall, s", "paired wall, s", "error, mm", "paired error, mm",
               "max, mm", "paired max, mm", "apart, mm"},
              prow);
  }
  for (const char* fac : {"ures", "vres", "layers", "dt"}) {
    Plot fig;
    fig.title = std::string("Convergence in ") + factor_title(fac);
    fig.x_label = factor_title(fac);
    fig.y_label = "error against the finest run, mm";
    fig.log_x = std::string(fac) == "dt";
    PlotSeries mean_s{"mean ± SD", {}, {}, true, true, {}}, max_s{"max", {}, {}, true, true, {}};
    for (const auto& k : r.runs) {
      if (k.factor != fac || k.reference || !std::isfinite(k.error_mean_mm)) continue;
      mean_s.x.push_back(std::stod(k.value));
      mean_s.y.push_back(k.error_mean_mm);
      mean_s.y_error.push_back(k.error_sd_mm);
      max_s.x.push_back(std::stod(k.value));
      max_s.y.push_back(k.error_max_mm);
    }
    if (mean_s.x.empty()) continue;
    fig.series = {mean_s, max_s};
    // The paper's means where it gives them (its reference: the finest of its own series).
    PlotSeries paper{"paper (mean)", {}, {}, false, true, {}};
    for (const auto& [key, paper_mean] : kPaperMeans)
      if (key.first == fac) {
        paper.x.push_back(std::stod(key.second));
        paper.y.push_back(paper_mean);
      }
    if (!paper.x.empty()) fig.series.push_back(paper);
    const std::string file = std::string("convergence_") + fac + ".png";
    fig.write_png(f.path(file));
    rep.figure(file, fig.title + " (cf. the paper's Figs 10-12).");
  }
  // Time against error for every run that is not a reference (its error is 0 by definition).
  {
    Plot fig;
    fig.title = "Wall time against error, every run";
    fig.x_label = "wall time, s (one core)";
    fig.y_label = "mean error against its series' finest run, mm";
    fig.log_x = true;
    fig.log_y = true;
    for (const char* fac : {"ures", "vres", "layers", "dt"}) {
      PlotSeries s{fac, {}, {}, false, true, {}};
      for (const auto& k : r.runs)
        if (k.factor == fac && !k.reference && std::isfinite(k.error_mean_mm) &&
            k.error_mean_mm > 0 && k.wall_s > 0) {
          s.x.push_back(k.wall_s);
          s.y.push_back(k.error_mean_mm);
        }
      if (!s.x.empty()) fig.series.push_back(s);
    }
    if (!o.pair.empty()) {
      PlotSeries s{"paired", {}, {}, false, true, {}};
      for (const auto& k : r.runs)
        if (!k.reference && k.paired_status == "ok" && std::isfinite(k.paired_error_mean_mm) &&
            k.paired_error_mean_mm > 0 && k.paired_wall_s > 0) {
          s.x.push_back(k.paired_wall_s);
          s.y.push_back(k.paired_error_mean_mm);
        }
      if (!s.x.empty()) fig.series.push_back(s);
    }
    // The Pareto front: runs no other run beats in both time and error.
    PlotSeries front{"Pareto front", {}, {}, true, false, {}};
    std::vector<std::pair<double, double>> pts;
    for (const auto& s : fig.series)
      for (std::size_t i = 0; i < s.x.size(); ++i) pts.push_back({s.x[i], s.y[i]});
    std::sort(pts.begin(), pts.end());
    double best = std::numeric_limits<double>::infinity();
    for (const auto& [x, y] : pts)
      if (y < best) {
        best = y;
        front.x.push_back(x);
        front.y.push_back(y);
      }
    if (!pts.empty()) {
      fig.series.push_back(front);
      fig.write_png(f.path("pareto.png"));
      rep.figure("pareto.png",
                 "Every run's wall time against its error; the line joins the runs that no "
                 "other run beats in both.");
    }
  }
  rep.how_made(o.command, r.workers, r.wall_s);
  rep.write(f.dir());
}

}  // namespace

}  // namespace mvtwin::studies
