#include "mvtwin/studies/clip_study.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>

#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/table_file.h"
#include "mvtwin/core/version.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/inverse/clip_prediction.h"
#include "mvtwin/studies/plot.h"
#include "mvtwin/studies/report.h"
#include "study_util.h"

namespace mvtwin::studies {
namespace fs = std::filesystem;
using detail::kNaN;
using nlohmann::json;

bool ClipStudyOptions::is_valid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (out.empty()) return fail("clip study: no output folder (--out)");
  if (folder.empty() && patients < 1) return fail("clip study: need at least one patient");
  if (jobs < 1 || jobs > 256) return fail("clip study: jobs must be 1 to 256");
  if (positions.empty()) return fail("clip study: no clip positions");
  for (double p : positions)
    if (!(p > 0 && p < 1)) return fail("clip study: clip positions must be in (0, 1)");
  if (!(pair_spacing > 0 && pair_spacing < 1))
    return fail("clip study: pair spacing must be in (0, 1)");
  if (!(two_clip_margin_mm2 >= 0)) return fail("clip study: two-clip margin must be >= 0 mm^2");
  if (pairs && candidates().size() == positions.size())
    return fail("clip study: no two positions are pair_spacing apart: no pairs to try");
  std::string e;
  if (!model.is_valid(&e)) return fail("clip study: " + e);
  if (!rating.is_valid(&e)) return fail("clip study: " + e);
  return true;
}

ClipStudyOptions ClipStudyOptions::quick() {
  ClipStudyOptions o;
  o.patients = 2;
  o.model.model.ures = 16;
  o.model.model.vres = 12;
  o.model.dt = 0.02;
  o.positions = {0.3, 0.5, 0.7};
  o.pair_spacing = 0.4;
  return o;
}

std::vector<std::vector<double>> ClipStudyOptions::candidates() const {
  std::vector<double> p = positions;
  std::sort(p.begin(), p.end());
  std::vector<std::vector<double>> c;
  for (double x : p) c.push_back({x});
  if (pairs)
    for (std::size_t i = 0; i < p.size(); ++i)
      for (std::size_t j = i + 1; j < p.size(); ++j)
        if (p[j] - p[i] >= pair_spacing - 1e-9) c.push_back({p[i], p[j]});
  return c;
}

json ClipStudyOptions::config() const {
  json c{{"model", detail::describe(model)},
         {"positions", positions},
         {"pairs", pairs},
         {"pair_spacing", pair_spacing}};
  if (folder.empty()) {
    c.update({{"seed", seed}, {"patients", patients}, {"parameters", "hidden (true)"}});
  } else {
    c["folder"] = fs::absolute(folder).lexically_normal().string();
    c["defaults"] = detail::parameters_json(defaults);
  }
  return c;
}

namespace {

std::string sites_text(const std::vector<double>& p) {
  if (p.empty()) return "none";
  std::string s;
  for (double x : p) s += (s.empty() ? "" : " + ") + number(x, 2);
  return s;
}

json scenario_json(const ClipStudyScenario& s) {
  return {{"positions", s.positions},
          {"status", s.status},
          {"reason", s.reason},
          {"orifice_mm2", s.orifice_mm2},
          {"coaptation_mm", s.coaptation_mm},
          {"coapting_fraction", s.coapting_fraction},
          {"orifice_components", s.orifice_components},
          {"max_clip_gap_mm", s.max_clip_gap_mm},
          {"wall_s", s.wall_s}};
}

ClipStudyScenario scenario_from_json(const json& j) {
  ClipStudyScenario s;
  s.positions = j.at("positions").get<std::vector<double>>();
  s.status = j.at("status");
  s.reason = j.value("reason", "");
  s.orifice_mm2 = j.value("orifice_mm2", 0.0);
  s.coaptation_mm = j.value("coaptation_mm", 0.0);
  s.coapting_fraction = j.value("coapting_fraction", 0.0);
  s.orifice_components = j.value("orifice_components", 0);
  s.max_clip_gap_mm = j.value("max_clip_gap_mm", 0.0);
  s.wall_s = j.value("wall_s", 0.0);
  return s;
}

struct Entry {
  std::string name;  ///< record prefix
  std::string id, pathology;
  fs::path file;  ///< empty for virtual patients
  int index = 0;
};

void write_outputs(const ClipStudyOptions& o, const ClipStudyResult& r, const StudyFolder& f);

}  // namespace

ClipStudyResult run_clip_study(const ClipStudyOptions& o, WorkPool& pool) {
  std::string err;
  if (!o.is_valid(&err)) throw Error(err);
  const auto t0 = std::chrono::steady_clock::now();
  const std::unique_ptr<StudyFolder> folder = open_study_folder(pool, o.out, "clip", o.config());

  std::vector<Entry> entries;
  if (o.folder.empty()) {
    for (int i = 0; i < o.patients; ++i) {
      const CohortMember m = cohort_member(o.seed, i);
      char name[32];
      std::snprintf(name, sizeof name, "patient_%04d", i);
      entries.push_back({name, m.id, std::string(pathology_name(m.pathology)), {}, i});
    }
  } else {
    const std::vector<fs::path> files = patient_files(o.folder);
    for (std::size_t i = 0; i < files.size(); ++i)
      entries.push_back({files[i].stem().string(), "", "", files[i], static_cast<int>(i)});
  }

  // Every (patient, scenario) is one item: scenarios of one patient spread over the pool too.
  std::vector<std::vector<double>> cands{{}};  // no clip first
  for (auto& c : o.candidates()) cands.push_back(c);
  const int per = static_cast<int>(cands.size());
  const int n = static_cast<int>(entries.size()) * per;

  // Patients are built (or read) once per process, on first use.
  std::mutex patients_mutex;
  std::map<int, std::shared_ptr<const Patient>> patients;
  std::map<int, std::string> load_errors;
  auto patient_of = [&](int e) -> std::shared_ptr<const Patient> {
    std::lock_guard<std::mutex> lock(patients_mutex);
    if (auto it = patients.find(e); it != patients.end()) return it->second;
    if (load_errors.count(e)) throw Error(load_errors[e]);
    try {
      const Entry& en = entries[static_cast<std::size_t>(e)];
      std::shared_ptr<const Patient> p;
      if (en.file.empty()) {
        p = std::make_shared<const Patient>(make_cohort_patient(o.seed, en.index));
      } else {
        std::lock_guard<std::mutex> h5(hdf5_mutex());
        p = std::make_shared<const Patient>(read_patient(en.file, false));
      }
      patients[e] = p;
      return p;
    } catch (const std::exception& ex) {
      load_errors[e] = ex.what();
      throw;
    }
  };

  std::mutex progress_mutex;
  std::atomic<int> done{0};
  auto report = [&](const std::string& msg) {
    if (!o.progress) return;
    std::lock_guard<std::mutex> lock(progress_mutex);
    o.progress({"simulate", done, n, msg});
  };
  const auto out = pool.map(n, o.jobs, [&](int item) -> std::string {
    const int e = item / per, s = item % per;
    const Entry& en = entries[static_cast<std::size_t>(e)];
    const std::string name = en.name + "_scenario_" + std::to_string(s);
    if (auto rec = folder->record(name)) {
      ++done;
      report(name + ": done before (resumed)");
      return rec->dump();
    }
    ClipStudyScenario sc;
    sc.positions = cands[static_cast<std::size_t>(s)];
    json extra;
    try {
      const std::shared_ptr<const Patient> p = patient_of(e);
      const ValveParameters par = p->truth ? p->truth->parameters : o.defaults;
      std::vector<inverse::ClipSite> sites;
      for (double x : sc.positions) sites.push_back({x, 1.0});
      const auto t = std::chrono::steady_clock::now();
      const inverse::ClipScenario r = inverse::simulate_clips(*p, par, o.model, {sites}, 1).front();
      sc.wall_s = detail::seconds_since(t);
      const inverse::ClosureQuality& q = r.quality;
      if (!q.converged) throw Error(q.reason);
      sc.orifice_mm2 = q.orifice.aroa_mm2;
      sc.coaptation_mm = q.orifice.coaptation_length_mm;
      sc.coapting_fraction = q.orifice.coapting_fraction;
      sc.orifice_components = static_cast<int>(q.orifice.openings.size());
      for (double g : q.clip_gap_mm) sc.max_clip_gap_mm = std::max(sc.max_clip_gap_mm, g);
      extra = {{"id", p->id},
               {"pathology", p->truth ? std::string(pathology_name(p->truth->pathology))
                                      : std::string("unknown")},
               {"synthetic", p->synthetic || p->truth.has_value()},
               {"parameters_from", p->truth ? "hidden (true) parameters" : "default parameters"}};
    } catch (const std::exception& ex) {
      sc.status = "failed";
      sc.reason = ex.what();
    }
    json j = scenario_json(sc);
    j["patient"] = extra;
    folder->save_record(name, j);
    ++done;
    report(name + " (" + sites_text(sc.positions) + "): " +
           (sc.status == "ok" ? number(sc.orifice_mm2, 1) + " mm^2" : "failed: " + sc.reason));
    return j.dump();
  });

  ClipStudyResult res;
  for (std::size_t e = 0; e < entries.size(); ++e) {
    ClipStudyPatient cp;
    cp.id = entries[e].id.empty() ? entries[e].name : entries[e].id;
    cp.pathology = entries[e].pathology.empty() ? "unknown" : entries[e].pathology;
    for (int s = 0; s < per; ++s) {
      const json j =
          json::parse(out[e * static_cast<std::size_t>(per) + static_cast<std::size_t>(s)]);
      cp.scenarios.push_back(scenario_from_json(j));
      const json& pj = j.value("patient", json());
      if (pj.is_object() && pj.contains("id")) {
        cp.id = pj.at("id");
        cp.pathology = pj.at("pathology");
        cp.synthetic = pj.at("synthetic");
        cp.parameters_from = pj.at("parameters_from");
      }
    }
    const ClipStudyScenario& before = cp.scenarios.front();
    if (before.status != "ok") {
      cp.status = "failed";
      cp.reason = "the closure without a clip failed: " + before.reason;
    }
    auto best = [&](std::size_t clips) {
      int b = -1;
      for (int s = 1; s < per; ++s) {
        const auto& sc = cp.scenarios[static_cast<std::size_t>(s)];
        if (sc.positions.size() != clips || sc.status != "ok") continue;
        if (b < 0 || sc.orifice_mm2 < cp.scenarios[static_cast<std::size_t>(b)].orifice_mm2) b = s;
      }
      return b;
    };
    cp.best_single = best(1);
    cp.best_pair = best(2);
    auto rate = [&](int s) {
      if (s < 0) return std::string("-");
      const auto& sc = cp.scenarios[static_cast<std::size_t>(s)];
      if (sc.status != "ok") return std::string("-");
      return o.rating.rate(0.611 * sc.orifice_mm2, std::nan(""));
    };
    cp.rating_before = rate(0);
    cp.rating_single = rate(cp.best_single);
    cp.rating_pair = rate(cp.best_pair);
    cp.two_clips_win = cp.best_pair >= 0 &&
                       (cp.best_single < 0 ||
                        cp.scenarios[static_cast<std::size_t>(cp.best_pair)].orifice_mm2 <=
                            cp.scenarios[static_cast<std::size_t>(cp.best_single)].orifice_mm2 -
                                o.two_clip_margin_mm2);
    res.patients.push_back(std::move(cp));
  }

  // Summary: overall and per pathology.
  auto summarize = [&](const std::vector<const ClipStudyPatient*>& ps) {
    std::vector<double> before, single, pair, best, gap1, gap2;
    int failed = 0, wins = 0, with_pairs = 0;
    for (const auto* p : ps) {
      if (p->status != "ok") {
        ++failed;
        continue;
      }
      before.push_back(p->scenarios.front().orifice_mm2);
      const double s1 = p->best_single >= 0
                            ? p->scenarios[static_cast<std::size_t>(p->best_single)].orifice_mm2
                            : kNaN;
      const double s2 = p->best_pair >= 0
                            ? p->scenarios[static_cast<std::size_t>(p->best_pair)].orifice_mm2
                            : kNaN;
      single.push_back(s1);
      pair.push_back(s2);
      best.push_back(p->two_clips_win ? s2 : s1);
      if (p->best_single >= 0)
        gap1.push_back(p->scenarios[static_cast<std::size_t>(p->best_single)].max_clip_gap_mm);
      if (p->best_pair >= 0) {
        gap2.push_back(p->scenarios[static_cast<std::size_t>(p->best_pair)].max_clip_gap_mm);
        ++with_pairs;
      }
      wins += p->two_clips_win ? 1 : 0;
    }
    return json{{"patients", ps.size()},
                {"failed", failed},
                {"orifice_before_mm2", detail::stats_json(before)},
                {"orifice_best_single_mm2", detail::stats_json(single)},
                {"orifice_best_pair_mm2", detail::stats_json(pair)},
                {"orifice_best_mm2", detail::stats_json(best)},
                {"clip_gap_single_mm", detail::stats_json(gap1)},
                {"clip_gap_pair_mm", detail::stats_json(gap2)},
                {"two_clips_win", wins},
                {"with_pairs", with_pairs}};
  };
  std::vector<const ClipStudyPatient*> all;
  std::map<std::string, std::vector<const ClipStudyPatient*>> by;
  for (const auto& p : res.patients) {
    all.push_back(&p);
    by[p.pathology].push_back(&p);
  }
  res.summary["overall"] = summarize(all);
  for (const auto& [k, v] : by) res.summary["by_pathology"][k] = summarize(v);
  res.workers = pool.describe();
  res.wall_s = detail::seconds_since(t0);
  if (pool.is_root()) write_outputs(o, res, *folder);
  pool.barrier();
  return res;
}

namespace {

using detail::nullable;

std::string stat_text(const json& s, int digits = 1) { return detail::stats_text(s, digits); }

void write_outputs(const ClipStudyOptions& o, const ClipStudyResult& r, const StudyFolder& f) {
  json patients = json::array();
  for (const auto& p : r.patients) {
    json sc = json::array();
    for (const auto& s : p.scenarios) sc.push_back(scenario_json(s));
    auto pos = [&](int s) {
      return s < 0 ? json(nullptr) : json(p.scenarios[static_cast<std::size_t>(s)].positions);
    };
    auto orifice = [&](int s) {
      return s < 0 ? json(nullptr) : nullable(p.scenarios[static_cast<std::size_t>(s)].orifice_mm2);
    };
    patients.push_back({{"id", p.id},
                        {"pathology", p.pathology},
                        {"synthetic", p.synthetic},
                        {"parameters_from", p.parameters_from},
                        {"status", p.status},
                        {"reason", p.reason},
                        {"orifice_before_mm2", p.status == "ok" ? orifice(0) : json(nullptr)},
                        {"best_single", pos(p.best_single)},
                        {"orifice_best_single_mm2", orifice(p.best_single)},
                        {"best_pair", pos(p.best_pair)},
                        {"orifice_best_pair_mm2", orifice(p.best_pair)},
                        {"two_clips_win", p.two_clips_win},
                        {"rating_before", p.rating_before},
                        {"rating_best_single", p.rating_single},
                        {"rating_best_pair", p.rating_pair},
                        {"scenarios", sc}});
  }
  json prov = detail::provenance(o.command, r.workers, r.wall_s);
  prov["seed"] = o.folder.empty() ? json(o.seed) : json(nullptr);
  write_json(f.path("study.json"), {{"format", "mvtwin-clip-study"},
                                    {"study", "clip"},
                                    {"config", o.config()},
                                    {"two_clip_margin_mm2", o.two_clip_margin_mm2},
                                    {"provenance", prov},
                                    {"summary", r.summary},
                                    {"patients", patients}});
  TableFile t;
  t.format = "mvtwin-clip-study";
  t.attributes = {
      {"mvtwin_version", kVersion}, {"command", o.command}, {"config", o.config().dump()}};
  TableColumn id{"patient", "", {}, {}}, path{"pathology", "", {}, {}},
      status{"status", "", {}, {}}, sites{"sites", "", {}, {}},
      orifice{"orifice_mm2", "mm^2", {}, {}}, coapt{"coaptation_mm", "mm", {}, {}},
      gap{"max_clip_gap_mm", "mm", {}, {}}, clips{"clips", "", {}, {}};
  for (const auto& p : r.patients)
    for (const auto& s : p.scenarios) {
      id.strings.push_back(p.id);
      path.strings.push_back(p.pathology);
      status.strings.push_back(s.status);
      sites.strings.push_back(sites_text(s.positions));
      clips.numbers.push_back(static_cast<double>(s.positions.size()));
      const bool ok = s.status == "ok";
      orifice.numbers.push_back(ok ? s.orifice_mm2 : kNaN);
      coapt.numbers.push_back(ok ? s.coaptation_mm : kNaN);
      gap.numbers.push_back(ok && !s.positions.empty() ? s.max_clip_gap_mm : kNaN);
    }
  t.columns = {id, path, status, sites, clips, orifice, coapt, gap};
  write_table_file(f.path("study.h5"), t);

  const json& ov = r.summary.at("overall");
  Report rep("Clip study: one clip or two, and where");
  rep.paragraph(
      "The paper (" + std::string(kPaperCitation) +
      ") simulated the MitraClip interactively and found the post-clip closure qualitatively "
      "like the real outcome; it reports no cohort figures to compare with. Here every patient's "
      "closure is simulated without a clip, with a single clip at each of " +
      std::to_string(o.positions.size()) +
      " positions along the coaptation line (0 = "
      "anterolateral commissure, 1 = posteromedial, at the free edges)" +
      (o.pairs ? " and with every pair of them at least " + number(o.pair_spacing, 2) + " apart"
               : "") +
      ". Best: the smallest residual orifice at the end of closure. Two clips win when the best "
      "pair leaves at least " +
      number(o.two_clip_margin_mm2, 1) +
      " mm^2 less than the best single clip. Clip gap: the distance between the clipped "
      "leaflets' atrial surfaces at the end (the leaflet thickness when the clip holds).");
  rep.paragraph(
      o.folder.empty()
          ? "Patients: " + std::to_string(r.patients.size()) +
                " SYNTHETIC virtual patients (cohort seed " + std::to_string(o.seed) +
                "), simulated with their hidden parameters, so the figures are what a perfect "
                "calibration would predict."
          : "Patients: every patient file of `" + o.folder.string() +
                "`, at the default parameters.");
  rep.paragraph(
      "Model " + std::to_string(o.model.model.ures) + " x " + std::to_string(o.model.model.vres) +
      ", " + std::to_string(o.model.model.layers) + " layer(s), dt " + number(o.model.dt, 4) +
      " s. Rating from the effective regurgitant orifice (0.611 x the anatomic one): "
      "satisfactory without regurgitation (below 1 mm^2), passable when mild, unsatisfactory "
      "from moderate (ASE 2017: 20 mm^2) up.");
  rep.heading("Residual orifice");
  std::vector<std::vector<std::string>> rows;
  auto row = [&](const std::string& name, const json& s) {
    rows.push_back(
        {name, std::to_string(s.at("patients").get<int>()),
         std::to_string(s.at("failed").get<int>()), stat_text(s.at("orifice_before_mm2")),
         stat_text(s.at("orifice_best_single_mm2")), stat_text(s.at("orifice_best_pair_mm2")),
         std::to_string(s.at("two_clips_win").get<int>()) + " of " +
             std::to_string(s.at("patients").get<int>() - s.at("failed").get<int>()),
         stat_text(s.at("clip_gap_single_mm"), 2) + " / " +
             stat_text(s.at("clip_gap_pair_mm"), 2)});
  };
  for (const auto& [k, v] : r.summary.at("by_pathology").items()) row(k, v);
  row("all", ov);
  rep.table({"pathology", "patients", "failed", "no clip, mm^2", "best single, mm^2",
             "best pair, mm^2", "two clips win", "clip gap single / pair, mm"},
            rows);
  rep.heading("Per patient");
  rows.clear();
  for (const auto& p : r.patients) {
    if (p.status != "ok") {
      rows.push_back({p.id, p.pathology, "failed: " + p.reason, "", "", "", ""});
      continue;
    }
    auto cell = [&](int s) {
      if (s < 0) return std::string("-");
      const auto& sc = p.scenarios[static_cast<std::size_t>(s)];
      return number(sc.orifice_mm2, 1) + " at " + sites_text(sc.positions);
    };
    rows.push_back({p.id, p.pathology, number(p.scenarios.front().orifice_mm2, 1),
                    cell(p.best_single), cell(p.best_pair), p.two_clips_win ? "yes" : "no",
                    p.rating_before + " → " + (p.two_clips_win ? p.rating_pair : p.rating_single)});
  }
  rep.table({"patient", "pathology", "no clip, mm^2", "best single, mm^2 at", "best pair, mm^2 at",
             "two clips win", "rating before → after"},
            rows);
  {
    Plot fig;
    fig.title = "Residual orifice per patient";
    fig.y_label = "orifice at the end of closure, mm^2";
    PlotSeries b{"no clip", {}, {}, true, true, {}}, s1{"best single clip", {}, {}, true, true, {}},
        s2{"best pair", {}, {}, true, true, {}};
    for (const auto& p : r.patients) {
      if (p.status != "ok") continue;
      fig.categories.push_back(p.id.substr(p.id.rfind('-') + 1));
      b.y.push_back(p.scenarios.front().orifice_mm2);
      s1.y.push_back(p.best_single >= 0
                         ? p.scenarios[static_cast<std::size_t>(p.best_single)].orifice_mm2
                         : 0.0);
      s2.y.push_back(
          p.best_pair >= 0 ? p.scenarios[static_cast<std::size_t>(p.best_pair)].orifice_mm2 : 0.0);
    }
    fig.x_label = "patient (index in the cohort)";
    fig.series = {b, s1};
    if (o.pairs) fig.series.push_back(s2);
    if (!fig.categories.empty()) {
      fig.write_png(f.path("orifice.png"));
      rep.figure("orifice.png",
                 "Residual orifice without a clip, after the best single clip and "
                 "after the best pair.");
    }
  }
  {
    // The orifice over clip position, averaged over patients (single clips).
    Plot fig;
    fig.title = "Residual orifice against the clip's position (single clips)";
    fig.x_label = "position along the coaptation line (0 = anterolateral, 1 = posteromedial)";
    fig.y_label = "orifice, mm^2 (mean ± SD over patients)";
    PlotSeries s{"single clip", {}, {}, true, true, {}};
    std::vector<double> sorted = o.positions;
    std::sort(sorted.begin(), sorted.end());
    for (double x : sorted) {
      std::vector<double> v;
      for (const auto& p : r.patients)
        for (const auto& sc : p.scenarios)
          if (sc.positions.size() == 1 && std::abs(sc.positions[0] - x) < 1e-9 && sc.status == "ok")
            v.push_back(sc.orifice_mm2);
      const detail::Stats st = detail::stats(v);
      if (st.n == 0) continue;
      s.x.push_back(x);
      s.y.push_back(st.mean);
      s.y_error.push_back(std::isfinite(st.sd) ? st.sd : 0.0);
    }
    const double before = ov.at("orifice_before_mm2").at("mean").is_number()
                              ? ov.at("orifice_before_mm2").at("mean").get<double>()
                              : kNaN;
    if (std::isfinite(before)) fig.h_lines.push_back({before, "no clip (mean)"});
    if (!s.x.empty()) {
      fig.series = {s};
      fig.write_png(f.path("orifice_by_position.png"));
      rep.figure("orifice_by_position.png", "Where a single clip helps most, over the cohort.");
    }
  }
  rep.how_made(o.command, r.workers, r.wall_s);
  rep.write(f.dir());
}

}  // namespace

}  // namespace mvtwin::studies
