#include "mvtwin/studies/sensitivity_study.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <mutex>

#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
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

std::vector<SensitivityCase> sensitivity_cases() {
  std::vector<SensitivityCase> c;
  auto add = [&](std::string g, std::string l, std::vector<std::string> s) {
    SensitivityCase k;
    k.group = std::move(g);
    k.label = std::move(l);
    k.settings = std::move(s);
    c.push_back(std::move(k));
  };
  add("baseline", "baseline", {});
  add("motion", "annulus fixed", {"annulus_motion=off"});
  add("motion", "papillary tips fixed", {"papillary_motion=off"});
  for (int m : {56, 20, 16, 12})
    add("marginal chordae", std::to_string(m) + " marginal chordae",
        {"marginal_chordae=" + std::to_string(m)});
  add("chordae stiffness", "stiffness -30 %",
      {"marginal_stiffness_scale=0.7", "basal_stiffness_scale=0.7"});
  add("chordae stiffness", "stiffness +30 %",
      {"marginal_stiffness_scale=1.3", "basal_stiffness_scale=1.3"});
  add("rest length", "rest lengths -30 %", {"restlength=0.7"});
  add("rest length", "rest lengths +30 %", {"restlength=1.3"});
  return c;
}

bool SensitivityStudyOptions::is_valid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (out.empty()) return fail("sensitivity study: no output folder (--out)");
  if (patient < 0) return fail("sensitivity study: negative patient index");
  if (!(sample_s > 0) || sample_s > 1)
    return fail("sensitivity study: sample_s must be in (0, 1] s");
  if (jobs < 1 || jobs > 256) return fail("sensitivity study: jobs must be 1 to 256");
  std::string e;
  if (!model.is_valid(&e)) return fail("sensitivity study: " + e);
  return true;
}

SensitivityStudyOptions SensitivityStudyOptions::quick() {
  SensitivityStudyOptions o;
  o.model.model.ures = 16;
  o.model.model.vres = 12;
  o.model.dt = 0.02;
  return o;
}

json SensitivityStudyOptions::config() const {
  json c{{"model", detail::describe(model)}, {"sample_s", sample_s}};
  if (patient_file.empty())
    c.update({{"seed", seed},
              {"patient", patient},
              {"virtual_patient_edition", kVirtualPatientEdition}});
  else
    c["patient_file"] = fs::absolute(patient_file).lexically_normal().string();
  return c;
}

namespace {

json case_json(const SensitivityCase& k) {
  return {{"group", k.group},
          {"label", k.label},
          {"settings", k.settings},
          {"status", k.status},
          {"reason", k.reason},
          {"time_s", k.time_s},
          {"anterior_tip_mm", k.anterior_tip_mm},
          {"posterior_tip_mm", k.posterior_tip_mm},
          {"max_anterior_diff_mm", k.max_anterior_diff_mm},
          {"max_posterior_diff_mm", k.max_posterior_diff_mm},
          {"end_orifice_mm2", k.end_orifice_mm2},
          {"end_anterior_tip_mm", k.end_anterior_tip_mm},
          {"end_posterior_tip_mm", k.end_posterior_tip_mm},
          {"wall_s", k.wall_s}};
}

SensitivityCase case_from_json(const json& j) {
  SensitivityCase k;
  k.group = j.at("group");
  k.label = j.at("label");
  k.settings = j.at("settings").get<std::vector<std::string>>();
  k.status = j.at("status");
  k.reason = j.value("reason", "");
  k.time_s = j.at("time_s").get<std::vector<double>>();
  k.anterior_tip_mm = j.at("anterior_tip_mm").get<std::vector<double>>();
  k.posterior_tip_mm = j.at("posterior_tip_mm").get<std::vector<double>>();
  k.end_orifice_mm2 = j.value("end_orifice_mm2", 0.0);
  k.end_anterior_tip_mm = j.value("end_anterior_tip_mm", 0.0);
  k.end_posterior_tip_mm = j.value("end_posterior_tip_mm", 0.0);
  k.wall_s = j.value("wall_s", 0.0);
  return k;
}

/// Linear interpolation of (t, y) at time x (clamped at the ends).
double interpolate(const std::vector<double>& t, const std::vector<double>& y, double x) {
  if (t.empty()) return kNaN;
  if (x <= t.front()) return y.front();
  if (x >= t.back()) return y.back();
  const auto it = std::upper_bound(t.begin(), t.end(), x);
  const std::size_t i = static_cast<std::size_t>(it - t.begin());
  const double w = (x - t[i - 1]) / (t[i] - t[i - 1]);
  return (1 - w) * y[i - 1] + w * y[i];
}

double max_difference(const std::vector<double>& t, const std::vector<double>& y,
                      const std::vector<double>& bt, const std::vector<double>& by) {
  double m = 0;
  for (std::size_t i = 0; i < t.size(); ++i)
    m = std::max(m, std::abs(y[i] - interpolate(bt, by, t[i])));
  return m;
}

void write_outputs(const SensitivityStudyOptions& o, const SensitivityStudyResult& r,
                   const StudyFolder& f);

}  // namespace

SensitivityStudyResult run_sensitivity_study(const SensitivityStudyOptions& o, WorkPool& pool) {
  std::string err;
  if (!o.is_valid(&err)) throw Error(err);
  const auto t0 = std::chrono::steady_clock::now();
  const std::unique_ptr<StudyFolder> folder =
      open_study_folder(pool, o.out, "sensitivity", o.config());

  ValveParameters baseline;
  forward::ClosureOptions model = o.model;
  const Patient patient = detail::study_patient(o.seed, o.patient, o.patient_file, &baseline);
  model.progress = nullptr;
  // Record every sample_s of observed time (the simulated closure is `stretch` times longer).
  model.record_every =
      std::max(1, static_cast<int>(std::lround(o.sample_s * model.stretch / model.dt)));

  std::vector<SensitivityCase> cases = sensitivity_cases();
  const int n = static_cast<int>(cases.size());
  std::mutex progress_mutex;
  std::atomic<int> done{0};
  auto report = [&](const std::string& msg) {
    if (!o.progress) return;
    std::lock_guard<std::mutex> lock(progress_mutex);
    o.progress({"simulate", done, n, msg});
  };
  const auto out = pool.map(n, o.jobs, [&](int i) -> std::string {
    SensitivityCase k = cases[static_cast<std::size_t>(i)];
    const std::string name = "case_" + std::to_string(i);
    if (auto rec = folder->record(name)) {
      ++done;
      report(k.label + ": done before (resumed)");
      return rec->dump();
    }
    try {
      forward::ClosureOptions m = model;
      ValveParameters par = baseline;
      for (const std::string& s : k.settings) {
        if (s.rfind("restlength=", 0) == 0) {  // every rest-length factor times this
          const double f = std::stod(s.substr(11));
          for (double& x : par.restlength_factor) x *= f;
        } else if (s.rfind("marginal_stiffness_scale=", 0) == 0 ||
                   s.rfind("basal_stiffness_scale=", 0) == 0) {
          const double f = std::stod(s.substr(s.find('=') + 1));
          (s[0] == 'm' ? par.marginal_stiffness_scale : par.basal_stiffness_scale) *= f;
        } else {
          forward::apply_setting(s, &m, &par);
        }
      }
      const forward::ClosureResult r = forward::simulate_closure(patient.sequence, par, m);
      if (!r.summary.converged()) throw Error(r.summary.reason);
      for (const auto& s : r.samples) {
        k.time_s.push_back(s.observed_time_s);
        k.anterior_tip_mm.push_back(s.anterior_tip_mm);
        k.posterior_tip_mm.push_back(s.posterior_tip_mm);
      }
      k.end_orifice_mm2 = r.samples.back().orifice_area_mm2;
      k.end_anterior_tip_mm = r.samples.back().anterior_tip_mm;
      k.end_posterior_tip_mm = r.samples.back().posterior_tip_mm;
      k.wall_s = r.summary.wall_s;
    } catch (const std::exception& ex) {
      k.status = "failed";
      k.reason = ex.what();
    }
    const json j = case_json(k);
    folder->save_record(name, j);
    ++done;
    report(k.label +
           (k.status == "ok" ? ": " + number(k.wall_s, 1) + " s" : ": failed: " + k.reason));
    return j.dump();
  });

  SensitivityStudyResult res;
  res.patient_id = patient.id;
  res.synthetic = patient.synthetic || patient.truth.has_value();
  for (const auto& s : out) res.cases.push_back(case_from_json(json::parse(s)));
  const SensitivityCase& b = res.cases.front();
  for (auto& k : res.cases) {
    if (k.status != "ok" || b.status != "ok") {
      k.max_anterior_diff_mm = k.max_posterior_diff_mm = kNaN;
      continue;
    }
    k.max_anterior_diff_mm =
        max_difference(k.time_s, k.anterior_tip_mm, b.time_s, b.anterior_tip_mm);
    k.max_posterior_diff_mm =
        max_difference(k.time_s, k.posterior_tip_mm, b.time_s, b.posterior_tip_mm);
  }
  res.workers = pool.describe();
  res.wall_s = detail::seconds_since(t0);
  if (pool.is_root()) write_outputs(o, res, *folder);
  pool.barrier();
  return res;
}

namespace {

/// The paper's maximum tip differences (AL, PL) per group, mm (its Sec. 4.2).
struct PaperFigure {
  const char* group;
  const char* al;
  const char* pl;
};
const PaperFigure kPaper[] = {
    {"motion",
     "annulus fixed: the valve no longer closes; papillary tips fixed: the AL billows into the "
     "atrium",
     ""},
    {"marginal chordae", "<= 1.65", "<= 0.64"},
    {"chordae stiffness", "<= 0.44", "<= 0.46"},
    {"rest length", "10.03", "3.87"},
};

void write_outputs(const SensitivityStudyOptions& o, const SensitivityStudyResult& r,
                   const StudyFolder& f) {
  json cases = json::array();
  for (const auto& k : r.cases) {
    json j = case_json(k);
    j["max_anterior_diff_mm"] = detail::nullable(k.max_anterior_diff_mm);
    j["max_posterior_diff_mm"] = detail::nullable(k.max_posterior_diff_mm);
    cases.push_back(j);
  }
  json prov = detail::provenance(o.command, r.workers, r.wall_s);
  prov["seed"] = o.patient_file.empty() ? json(o.seed) : json(nullptr);
  write_json(f.path("study.json"), {{"format", "mvtwin-sensitivity-study"},
                                    {"study", "sensitivity"},
                                    {"patient", r.patient_id},
                                    {"synthetic", r.synthetic},
                                    {"config", o.config()},
                                    {"provenance", prov},
                                    {"cases", cases}});
  TableFile t;
  t.format = "mvtwin-sensitivity-study";
  t.attributes = {{"mvtwin_version", kVersion},
                  {"command", o.command},
                  {"patient", r.patient_id},
                  {"synthetic", r.synthetic ? "1" : "0"},
                  {"config", o.config().dump()}};
  TableColumn label{"case", "", {}, {}}, group{"group", "", {}, {}},
      al{"max_anterior_diff_mm", "mm", {}, {}}, pl{"max_posterior_diff_mm", "mm", {}, {}},
      orifice{"end_orifice_mm2", "mm^2", {}, {}};
  for (const auto& k : r.cases) {
    label.strings.push_back(k.label);
    group.strings.push_back(k.group);
    al.numbers.push_back(k.max_anterior_diff_mm);
    pl.numbers.push_back(k.max_posterior_diff_mm);
    orifice.numbers.push_back(k.status == "ok" ? k.end_orifice_mm2 : kNaN);
  }
  t.columns = {label, group, al, pl, orifice};
  write_table_file(f.path("study.h5"), t);

  Report rep("Sensitivity study: what moves the leaflet tips");
  rep.paragraph("Compared with " + std::string(kPaperCitation) + " (its Sec. 4.2 and Figs 13-14).");
  rep.paragraph(
      "Patient `" + r.patient_id + "`" +
      (r.synthetic ? " (SYNTHETIC, its hidden parameters as the baseline)" : "") + "; model " +
      std::to_string(o.model.model.ures) + " x " + std::to_string(o.model.model.vres) + ", " +
      std::to_string(o.model.model.layers) + " layer(s), dt " + number(o.model.dt, 4) +
      " s. Tip: the signed distance of each leaflet's tip (the middle of its free edge) to the "
      "annulus plane, positive towards the atrium, over the image clock; difference: the largest "
      "over time against the baseline.");
  rep.heading("mvtwin next to the paper");
  std::vector<std::vector<std::string>> rows;
  for (const auto& k : r.cases) {
    std::string paper_al = "-", paper_pl = "-";
    for (const auto& p : kPaper)
      if (k.group == p.group) {
        paper_al = p.al;
        paper_pl = p.pl;
      }
    if (k.group == "motion") paper_pl = "";
    rows.push_back(
        {k.label, k.status == "ok" ? number(k.max_anterior_diff_mm) : "failed: " + k.reason,
         k.status == "ok" ? number(k.max_posterior_diff_mm) : "-",
         k.status == "ok"
             ? number(k.end_anterior_tip_mm, 1) + " / " + number(k.end_posterior_tip_mm, 1)
             : "-",
         k.status == "ok" ? number(k.end_orifice_mm2, 1) : "-",
         k.group == "baseline" ? "" : paper_al, k.group == "baseline" ? "" : paper_pl});
  }
  rep.table({"case", "max AL tip difference, mm", "max PL tip difference, mm",
             "end tips AL / PL, mm", "end orifice, mm^2", "paper AL", "paper PL"},
            rows);
  for (const char* g : {"motion", "marginal chordae", "chordae stiffness", "rest length"}) {
    for (int leaflet = 0; leaflet < 2; ++leaflet) {
      Plot fig;
      fig.title = std::string(leaflet == 0 ? "Anterior" : "Posterior") + " leaflet tip: " + g;
      fig.x_label = "time, s (image clock)";
      fig.y_label = "tip to annulus plane, mm (+ atrial)";
      for (const auto& k : r.cases) {
        if (k.status != "ok" || (k.group != g && k.group != "baseline")) continue;
        fig.series.push_back({k.label,
                              k.time_s,
                              leaflet == 0 ? k.anterior_tip_mm : k.posterior_tip_mm,
                              true,
                              false,
                              {}});
      }
      if (fig.series.empty()) continue;
      fig.h_lines.push_back({0.0, "annulus plane"});
      std::string file = std::string(leaflet == 0 ? "al_" : "pl_") + g + ".png";
      std::replace(file.begin(), file.end(), ' ', '_');
      fig.write_png(f.path(file));
      rep.figure(file, fig.title + " (cf. the paper's Figs 13-14).");
    }
  }
  rep.how_made(o.command, r.workers, r.wall_s);
  rep.write(f.dir());
}

}  // namespace

}  // namespace mvtwin::studies
