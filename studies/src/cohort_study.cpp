#include "mvtwin/studies/cohort_study.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <mutex>
#include <set>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/closure_measures.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/point_to_mesh_distance.h"
#include "mvtwin/core/regurgitant_orifice.h"
#include "mvtwin/core/table_file.h"
#include "mvtwin/core/version.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/forward/chordae_tuning.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/inverse/calibration.h"
#include "mvtwin/inverse/closure_objective.h"
#include "mvtwin/studies/plot.h"
#include "mvtwin/studies/report.h"
#include "mvtwin/studies/scaling.h"
#include "study_util.h"

namespace mvtwin::studies {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using detail::describe;
using detail::kNaN;
using detail::parameters_json;
using detail::seconds_since;
using detail::stats_json;

double num(const json& j, const char* key) { return detail::number_at(j, key); }

/// One patient of the study: where its data come from.
struct Entry {
  std::string name;  ///< record name: patient_0003, or the file's stem
  std::string id, pathology;
  fs::path file;  ///< the observed patient file (cached observation or the given file)
  bool is_virtual = false;
};

const char* kRatings[] = {"satisfactory", "passable", "unsatisfactory"};

}  // namespace

// ---- rating and options ----------------------------------------------------------------------

std::string ClosureRating::rate(double eroa, double observed) const {
  if (!std::isfinite(eroa)) return "unsatisfactory";
  const MrGrade g = mr_grade_of(eroa);
  if (!std::isfinite(observed)) {
    return g == MrGrade::kNone   ? "satisfactory"
           : g == MrGrade::kMild ? "passable"
                                 : "unsatisfactory";
  }
  const double tol = std::max(match_mm2, match_fraction * observed),
               miss = std::abs(eroa - observed);
  if (miss <= tol) return "satisfactory";
  if (g == mr_grade_of(observed) || miss <= 2.0 * tol) return "passable";
  return "unsatisfactory";
}

bool ClosureRating::is_valid(std::string* error) const {
  if (!(match_mm2 >= 0 && match_fraction >= 0 && (match_mm2 > 0 || match_fraction > 0))) {
    if (error) *error = "rating: the EROA match tolerances must be >= 0 and not both 0";
    return false;
  }
  return true;
}

bool CohortStudyOptions::is_valid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (out.empty()) return fail("cohort study: no output folder (--out)");
  if (folder.empty() && (patients < 1 || patients > 100000))
    return fail("cohort study: patients must be 1 to 100000, not " + std::to_string(patients));
  if (!folder.empty() && !fs::is_directory(folder))
    return fail("cohort study: " + folder.string() + " is not a folder");
  if (jobs < 1 || jobs > 256) return fail("cohort study: jobs must be 1 to 256");
  if (max_simulations < 1) return fail("cohort study: max_simulations must be >= 1");
  if (!(restlength_tolerance > 0) || !std::isfinite(restlength_tolerance))
    return fail("cohort study: restlength_tolerance must be a positive number");
  std::string e;
  if (!model.is_valid(&e)) return fail("cohort study: model: " + e);
  if (calibrate && !fit_model.is_valid(&e)) return fail("cohort study: fit model: " + e);
  if (!observation.simulation.is_valid(&e)) return fail("cohort study: observation model: " + e);
  if (!(observation.noise_mm >= 0)) return fail("cohort study: observation noise must be >= 0 mm");
  if (!rating.is_valid(&e)) return fail("cohort study: " + e);
  if (static_cast<int>(method) < 0 || static_cast<int>(method) >= inverse::kNumFitMethods)
    return fail("cohort study: unknown fit method");
  return true;
}

forward::VirtualClosureOptions CohortStudyOptions::study_observation() {
  forward::VirtualClosureOptions v;
  v.tune_normal_chordae = true;  // a healthy valve closes (docs/virtual-patients.md)
  return v;
}

forward::ClosureOptions CohortStudyOptions::default_fit_model() {
  const forward::ClosureOptions model;
  return inverse::search_model_for(model).value_or(model);
}

CohortStudyOptions CohortStudyOptions::quick() {
  CohortStudyOptions o;
  o.patients = 5;
  o.calibrate = false;
  o.model.model.ures = 16;
  o.model.model.vres = 12;
  o.model.dt = 0.02;
  o.fit_model = o.model;
  o.observation.simulation = forward::ClosureOptions{};
  o.observation.simulation.model.ures = 20;
  o.observation.simulation.model.vres = 16;
  o.observation.simulation.dt = 0.01;
  o.observation.tune_normal_chordae = false;  // 13 closures at 30 x 30 per normal valve
  return o;
}

json CohortStudyOptions::config() const {
  json c{{"calibration_model", describe(model)},
         {"defaults", parameters_json(defaults)},
         {"calibrate", calibrate},
         {"rating", {{"match_mm2", rating.match_mm2}, {"match_fraction", rating.match_fraction}}}};
  if (calibrate)
    c.update({{"fit", fit},
              {"method", inverse::fit_method_name(method)},
              {"max_simulations", max_simulations},
              {"fit_model", describe(fit_model)}});
  if (calibrate) detail::add_calibration_scans(&c, fit);
  if (folder.empty()) {
    c.update(
        {{"patients", patients},
         {"seed", seed},
         {"virtual_patient_edition", kVirtualPatientEdition},
         {"observation_model", describe(observation.simulation)},
         {"observation_noise_mm", observation.noise_mm},
         {"normal_chordae_tuning",
          observation.tune_normal_chordae ? json(forward::kChordaeTuningEdition) : json(nullptr)}});
  } else {
    c["folder"] = fs::absolute(folder).lexically_normal().string();
  }
  return c;
}

// ---- a patient's record ------------------------------------------------------------------------

json CohortPatient::to_json() const {
  const auto n = detail::nullable;
  json j{{"index", index},
         {"id", id},
         {"pathology", pathology},
         {"file", file},
         {"synthetic", synthetic},
         {"status", status},
         {"error_default_mm", status == "ok" ? n(error_default_mm) : json(nullptr)},
         {"error_default_sd_mm", status == "ok" ? n(error_default_sd_mm) : json(nullptr)},
         {"error_default_p95_mm", status == "ok" ? n(error_default_p95_mm) : json(nullptr)},
         {"orifice_mm2", status == "ok" ? n(orifice_mm2) : json(nullptr)},
         {"orifice_observed_mm2", status == "ok" ? n(orifice_observed_mm2) : json(nullptr)},
         {"coaptation_mm", status == "ok" ? n(coaptation_mm) : json(nullptr)},
         {"coapting_fraction", status == "ok" ? n(coapting_fraction) : json(nullptr)},
         {"rating", rating.empty() ? json(nullptr) : json(rating)},
         {"error_calibrated_mm", n(error_calibrated_mm)},
         {"error_default_fit_model_mm", n(error_default_fit_model_mm)},
         {"error_calibrated_fit_model_mm", n(error_calibrated_fit_model_mm)},
         {"simulations", simulations},
         {"failed_simulations", failed_simulations},
         {"failures_by_outcome", failures_by_outcome},
         {"termination", termination},
         {"refinement", refinement},
         {"noise_fit_mm", n(noise_fit_mm)},
         {"fitted", fitted.is_null() ? json::object() : fitted},
         {"truth", truth.is_null() ? json::object() : truth},
         {"sd", sd.is_null() ? json::object() : sd},
         {"identified", identified.is_null() ? json::object() : identified},
         {"observe_s", observe_s},
         {"observed_with", observed_with.empty() ? json(nullptr) : json(observed_with)},
         {"default_s", default_s},
         {"calibrate_s", calibrate_s}};
  if (!reason.empty()) j["reason"] = reason;
  return j;
}

CohortPatient CohortPatient::from_json(const json& j) {
  CohortPatient p;
  p.index = j.value("index", 0);
  p.id = j.value("id", "");
  p.pathology = j.value("pathology", "");
  p.file = j.value("file", "");
  p.synthetic = j.value("synthetic", false);
  p.status = j.value("status", "failed");
  p.reason = j.value("reason", "");
  p.error_default_mm = num(j, "error_default_mm");
  p.error_default_sd_mm = num(j, "error_default_sd_mm");
  p.error_default_p95_mm = num(j, "error_default_p95_mm");
  p.orifice_mm2 = num(j, "orifice_mm2");
  p.orifice_observed_mm2 = num(j, "orifice_observed_mm2");
  p.coaptation_mm = num(j, "coaptation_mm");
  p.coapting_fraction = num(j, "coapting_fraction");
  p.rating = j.contains("rating") && j["rating"].is_string() ? j["rating"].get<std::string>() : "";
  p.error_calibrated_mm = num(j, "error_calibrated_mm");
  p.error_default_fit_model_mm = num(j, "error_default_fit_model_mm");
  p.error_calibrated_fit_model_mm = num(j, "error_calibrated_fit_model_mm");
  p.simulations = j.value("simulations", 0);
  p.failed_simulations = j.value("failed_simulations", 0);
  p.failures_by_outcome = j.value("failures_by_outcome", std::map<std::string, int>{});
  p.termination = j.value("termination", "");
  p.refinement = j.value("refinement", "");
  p.noise_fit_mm = num(j, "noise_fit_mm");
  p.fitted = j.value("fitted", json::object());
  p.truth = j.value("truth", json::object());
  p.sd = j.value("sd", json::object());
  p.identified = j.value("identified", json::object());
  p.observe_s = j.value("observe_s", 0.0);
  p.observed_with = j.contains("observed_with") && j["observed_with"].is_string()
                        ? j["observed_with"].get<std::string>()
                        : "";
  p.default_s = j.value("default_s", 0.0);
  p.calibrate_s = j.value("calibrate_s", 0.0);
  return p;
}

// ---- the study ---------------------------------------------------------------------------------

namespace {

void write_outputs(const CohortStudyOptions& o, const CohortStudyResult& r,
                   const StudyFolder& folder);

}  // namespace

CohortStudyResult run_cohort_study(const CohortStudyOptions& o, WorkPool& pool) {
  std::string err;
  if (!o.is_valid(&err)) throw Error(err);
  const auto t_start = std::chrono::steady_clock::now();
  const json config = o.config();
  const std::unique_ptr<StudyFolder> folder = open_study_folder(pool, o.out, "cohort", config);

  std::mutex progress_mutex;
  auto report = [&](const std::string& stage, int done, int total, const std::string& msg) {
    if (!o.progress) return;
    std::lock_guard<std::mutex> lock(progress_mutex);
    o.progress({stage, done, total, msg});
  };

  // The patients.
  std::vector<Entry> entries;
  if (o.folder.empty()) {
    const fs::path cache = o.cache.empty() ? o.out / "observed" : o.cache;
    if (pool.is_root()) create_output_directory(cache);
    for (int i = 0; i < o.patients; ++i) {
      const CohortMember m = cohort_member(o.seed, i);
      char name[32];
      std::snprintf(name, sizeof name, "patient_%04d", i);
      entries.push_back({name, m.id, std::string(pathology_name(m.pathology)),
                         detail::observed_file(cache, m, o.observation), true});
    }
  } else {
    const std::vector<fs::path> files = patient_files(o.folder);
    for (const auto& f : files) entries.push_back({f.stem().string(), "", "", f, false});
  }
  pool.barrier();
  const int n = static_cast<int>(entries.size());
  std::atomic<int> done{0};

  // Stage 1: the virtual patients' observed closures (cached; the one-time cost).
  std::vector<std::string> observe_failed(entries.size());
  std::vector<double> observe_s(entries.size(), 0.0);
  if (o.folder.empty()) {
    const auto out = pool.map(n, o.jobs, [&](int i) -> std::string {
      const Entry& e = entries[static_cast<std::size_t>(i)];
      json r{{"s", 0.0}};
      try {
        report("observe", done, n, e.id + ": its observed closure (fine model; cached once made)");
        r["s"] = detail::ensure_observed(e.file, o.seed, i, o.observation);
      } catch (const std::exception& ex) {
        r["reason"] = std::string("observation failed: ") + ex.what();
      }
      report("observe", ++done, n, e.id + (r.contains("reason") ? ": failed" : ": observed"));
      return r.dump();
    });
    for (int i = 0; i < n; ++i) {
      const json r = json::parse(out[static_cast<std::size_t>(i)]);
      observe_s[static_cast<std::size_t>(i)] = r.value("s", 0.0);
      observe_failed[static_cast<std::size_t>(i)] = r.value("reason", "");
    }
  }

  // Stage 2: default parameters.
  const inverse::ParameterSpace space_template(o.fit, o.defaults);
  auto load = [&](const Entry& e) {
    std::lock_guard<std::mutex> lock(hdf5_mutex());
    return read_patient(e.file, false);
  };
  done = 0;
  auto defaults = pool.map(n, o.jobs, [&](int i) -> std::string {
    const Entry& e = entries[static_cast<std::size_t>(i)];
    if (auto rec = folder->record(e.name); rec && rec->value("stage_default", false)) {
      report("default", ++done, n, e.name + ": done before (resumed)");
      return rec->dump();
    }
    CohortPatient c;
    c.index = i;
    c.id = e.id;
    c.pathology = e.pathology;
    c.file = e.file.string();
    c.synthetic = e.is_virtual;
    c.observe_s = observe_s[static_cast<std::size_t>(i)];
    c.error_calibrated_mm = kNaN;
    try {
      if (!observe_failed[static_cast<std::size_t>(i)].empty())
        throw Error(observe_failed[static_cast<std::size_t>(i)]);
      const Patient p = load(e);
      c.id = p.id;
      c.synthetic = p.synthetic || p.truth.has_value();
      if (p.truth) c.pathology = std::string(pathology_name(p.truth->pathology));
      if (p.truth && e.is_virtual)
        c.observed_with = p.truth->observed_with.empty() ? "as given" : p.truth->observed_with;
      if (c.pathology.empty()) c.pathology = "unknown";
      const auto t0 = std::chrono::steady_clock::now();
      inverse::ObjectiveOptions oo;
      oo.simulation = o.model;
      const inverse::ClosureObjective obj(p, space_template, oo);
      const forward::ClosureResult r = obj.simulate(obj.space().start());
      const inverse::Evaluation ev = obj.compare(r);
      if (!ev.ok) throw Error("default simulation failed: " + ev.reason);
      const DistanceStats d = distance_stats(
          std::vector<double>(ev.residuals.data(), ev.residuals.data() + ev.residuals.size()));
      c.error_default_mm = d.mean;
      c.error_default_sd_mm = d.sd;
      c.error_default_p95_mm = d.p95;
      // The effective regurgitant orifice, simulated and observed (a virtual patient's: its
      // observation model's closed valve; a real patient's closed frame is too coarse for it).
      c.orifice_mm2 = r.orifice ? r.orifice->eroa_mm2 : kNaN;
      c.coaptation_mm = r.orifice ? r.orifice->coaptation_length_mm : kNaN;
      c.coapting_fraction = r.orifice ? r.orifice->coapting_fraction : kNaN;
      c.orifice_observed_mm2 =
          p.truth && p.truth->closed_orifice ? p.truth->closed_orifice->eroa_mm2 : kNaN;
      c.rating = o.rating.rate(c.orifice_mm2, c.orifice_observed_mm2);
      c.default_s = seconds_since(t0);
      if (p.truth) c.truth = parameters_json(p.truth->parameters);
    } catch (const std::exception& ex) {
      c.status = "failed";
      c.reason = ex.what();
    }
    json rec = c.to_json();
    rec["stage_default"] = true;
    folder->save_record(e.name, rec);
    report("default", ++done, n,
           e.name + " (" + c.pathology + "): " +
               (c.status == "ok" ? number(c.error_default_mm) + " mm, " + c.rating
                                 : "failed: " + c.reason));
    return rec.dump();
  });

  // Stage 3: calibration, `jobs` patients at a time per process (the optimizer is sequential:
  // one core each), each with the cores left over when fewer patients than jobs remain.
  std::vector<std::string> finals = defaults;
  if (o.calibrate) {
    done = 0;
    const int per_rank = (n + pool.size() - 1) / pool.size();
    finals = pool.map(n, std::min(o.jobs, std::max(1, per_rank)), [&](int i) -> std::string {
      const Entry& e = entries[static_cast<std::size_t>(i)];
      json rec = json::parse(defaults[static_cast<std::size_t>(i)]);
      if (auto r = folder->record(e.name); r && r->value("stage_calibrated", false)) {
        report("calibrate", ++done, n, e.name + ": done before (resumed)");
        return r->dump();
      }
      if (rec.value("status", "") != "ok") {
        report("calibrate", ++done, n, e.name + ": skipped (" + rec.value("reason", "") + ")");
        return rec.dump();
      }
      CohortPatient c = CohortPatient::from_json(rec);
      try {
        const Patient p = load(e);
        const auto t0 = std::chrono::steady_clock::now();
        // The objective is the reporting model and the fit model the search model (start,
        // scan and optimizer); calibrate() refines the search's fit on the reporting model, or
        // runs on it alone when the two are the same model (inverse::CalibrationOptions::
        // search_model), so that the calibrated error is the reporting model's best, measured
        // as the defaults were.
        inverse::ObjectiveOptions oo;
        oo.simulation = o.model;
        inverse::ClosureObjective obj(p, space_template, oo);
        inverse::CalibrationOptions co;
        co.method = o.method;
        co.jobs = std::max(1, o.jobs / std::max(1, std::min(o.jobs, n - i)));
        co.max_simulations = o.max_simulations;
        co.search_model = o.fit_model;
        const inverse::CalibrationResult r = inverse::calibrate(obj, co);
        const bool searched = r.search_simulations > 0;
        c.error_default_fit_model_mm = searched ? r.search_error_before_mm : r.error_before_mm;
        c.error_calibrated_fit_model_mm = searched ? r.search_error_after_mm : r.error_after_mm;
        c.error_calibrated_mm = r.error_after_mm;
        c.refinement = r.refinement;
        c.simulations = r.simulations;
        c.failed_simulations = r.failed_simulations;
        c.failures_by_outcome = r.failures_by_outcome;
        c.termination = r.termination;
        c.noise_fit_mm = r.noise_mm;
        c.fitted = json::object();
        c.sd = json::object();
        c.identified = json::object();
        for (int k = 0; k < obj.space().size(); ++k) {
          const std::string& name = obj.space().specs()[k].name;
          c.fitted[name] = r.fitted[k];
          c.sd[name] = detail::nullable(r.sd[k]);
          c.identified[name] = static_cast<bool>(r.identified[k]);
        }
        if (p.truth) {  // the truth in the fit's (user) units, e.g. mmHg for the pressure
          const Eigen::VectorXd t = obj.space().values_of(p.truth->parameters);
          for (int k = 0; k < obj.space().size(); ++k) c.truth[obj.space().specs()[k].name] = t[k];
        }
        c.calibrate_s = seconds_since(t0);
      } catch (const std::exception& ex) {
        c.reason = std::string("calibration failed: ") + ex.what();  // the default stage stands
      }
      json out = c.to_json();
      out["stage_default"] = true;
      out["stage_calibrated"] = true;
      folder->save_record(e.name, out);
      report("calibrate", ++done, n,
             e.name + ": " + number(c.error_default_mm) + " -> " + number(c.error_calibrated_mm) +
                 " mm");
      return out.dump();
    });
  }

  CohortStudyResult result;
  for (const auto& s : finals) result.patients.push_back(CohortPatient::from_json(json::parse(s)));
  result.workers = pool.describe();

  // Summary: overall, per pathology, per rating; parameter errors against the truth.
  auto summarize = [&](const std::vector<const CohortPatient*>& ps) {
    std::vector<double> def, cal, p95, orifice, orifice_obs;
    std::map<std::string, int> ratings;
    int failed = 0;
    for (const auto* p : ps) {
      if (p->status != "ok") {
        ++failed;
        continue;
      }
      def.push_back(p->error_default_mm);
      p95.push_back(p->error_default_p95_mm);
      orifice.push_back(p->orifice_mm2);
      orifice_obs.push_back(p->orifice_observed_mm2);
      cal.push_back(p->error_calibrated_mm);
      ++ratings[p->rating];
    }
    json rj = json::object();
    for (const char* k : kRatings) rj[k] = ratings[k];
    return json{{"patients", ps.size()},
                {"failed", failed},
                {"error_default_mm", stats_json(def)},
                {"error_default_p95_mm", stats_json(p95)},
                {"error_calibrated_mm", stats_json(cal)},
                {"orifice_mm2", stats_json(orifice)},
                {"orifice_observed_mm2", stats_json(orifice_obs)},
                {"ratings", rj}};
  };
  std::vector<const CohortPatient*> all;
  std::map<std::string, std::vector<const CohortPatient*>> by_path, by_rating;
  for (const auto& p : result.patients) {
    all.push_back(&p);
    by_path[p.pathology].push_back(&p);
    if (p.status == "ok") by_rating[p.rating].push_back(&p);
  }
  result.summary["overall"] = summarize(all);
  for (const auto& [k, v] : by_path) result.summary["by_pathology"][k] = summarize(v);
  for (const auto& [k, v] : by_rating) result.summary["by_rating"][k] = summarize(v);
  // Parameter recovery, over every fit and over the parameters the data identify.
  std::map<std::string, std::vector<double>> perr, perr_identified;
  int rl_identified = 0, rl_within = 0, rl_unidentified = 0;
  for (const auto& p : result.patients)
    for (const auto& [name, v] : p.fitted.items()) {
      if (!p.truth.contains(name)) continue;
      const double d = std::abs(v.get<double>() - p.truth[name].get<double>());
      perr[name].push_back(d);
      const bool ident = p.identified.value(name, false);
      if (ident) perr_identified[name].push_back(d);
      if (name.rfind("restlength_factor_", 0) != 0) continue;
      if (!ident) {
        ++rl_unidentified;
        continue;
      }
      ++rl_identified;
      if (d <= o.restlength_tolerance) ++rl_within;
    }
  json pj = json::object(), pij = json::object();
  for (const auto& [name, v] : perr) pj[name] = stats_json(v);
  for (const auto& [name, v] : perr_identified) pij[name] = stats_json(v);
  // How the virtual patients were observed: by the observation model as given, by a safer
  // retry (forward::observation_attempts), or not at all (the patient lost to the solver).
  {
    int as_given = 0, lost = 0;
    std::map<std::string, int> retried;
    for (const auto& p : result.patients) {
      if (p.reason.rfind("observation failed", 0) == 0)
        ++lost;
      else if (p.observed_with == "as given")
        ++as_given;
      else if (!p.observed_with.empty())
        ++retried[p.observed_with];
    }
    result.summary["observations"] = {{"as_given", as_given}, {"retried", retried}, {"lost", lost}};
  }
  result.summary["fitted_minus_truth_abs"] = pj;
  result.summary["fitted_minus_truth_abs_identified"] = pij;
  if (o.calibrate) {
    std::vector<double> sims, secs, ratio, noise_fit;
    int failed_sims = 0, calibrated = 0;
    std::map<std::string, int> failures;
    for (const auto& p : result.patients) {
      if (!std::isfinite(p.error_calibrated_mm)) continue;
      ++calibrated;
      sims.push_back(p.simulations);
      secs.push_back(p.calibrate_s);
      failed_sims += p.failed_simulations;
      for (const auto& [kind, count] : p.failures_by_outcome) failures[kind] += count;
      if (std::isfinite(p.noise_fit_mm)) noise_fit.push_back(p.noise_fit_mm);
      if (p.synthetic && o.folder.empty() && o.observation.noise_mm > 0)
        ratio.push_back(p.error_calibrated_mm / o.observation.noise_mm);
    }
    result.summary["calibration"] = {{"method", inverse::fit_method_name(o.method)},
                                     {"calibrated", calibrated},
                                     {"simulations", stats_json(sims)},
                                     {"failed_simulations", failed_sims},
                                     {"failures_by_outcome", failures},
                                     {"calibrate_s", stats_json(secs)},
                                     {"noise_fit_mm", stats_json(noise_fit)},
                                     {"error_calibrated_over_noise", stats_json(ratio)},
                                     {"restlength_recovery",
                                      {{"tolerance", o.restlength_tolerance},
                                       {"identified", rl_identified},
                                       {"identified_within_tolerance", rl_within},
                                       {"unidentified", rl_unidentified}}}};
  }
  result.wall_s = seconds_since(t_start);
  if (pool.is_root()) write_outputs(o, result, *folder);
  pool.barrier();
  return result;
}

namespace {

void write_outputs(const CohortStudyOptions& o, const CohortStudyResult& r,
                   const StudyFolder& folder) {
  json prov = detail::provenance(o.command, r.workers, r.wall_s);
  prov["seed"] = o.folder.empty() ? json(o.seed) : json(nullptr);
  bool any_synthetic = false, any_real = false;
  json patients = json::array();
  for (const auto& p : r.patients) {
    patients.push_back(p.to_json());
    (p.synthetic ? any_synthetic : any_real) = true;
  }
  write_json(folder.path("study.json"), {{"format", "mvtwin-cohort-study"},
                                         {"study", "cohort"},
                                         {"synthetic", any_synthetic && !any_real},
                                         {"config", o.config()},
                                         {"provenance", prov},
                                         {"summary", r.summary},
                                         {"patients", patients}});
  // The same table as HDF5 (h5py, pandas).
  TableFile t;
  t.format = "mvtwin-cohort-study";
  t.attributes = {{"mvtwin_version", kVersion},
                  {"command", o.command},
                  {"created_utc", prov["created_utc"].get<std::string>()},
                  {"seed", o.folder.empty() ? std::to_string(o.seed) : ""},
                  {"synthetic", any_synthetic && !any_real ? "1" : "0"},
                  {"config", o.config().dump()}};
  auto strings = [&](const char* name, auto get) {
    TableColumn c;
    c.name = name;
    for (const auto& p : r.patients) c.strings.push_back(get(p));
    t.columns.push_back(std::move(c));
  };
  auto numbers = [&](const char* name, const char* units, auto get) {
    TableColumn c;
    c.name = name;
    c.units = units;
    for (const auto& p : r.patients) c.numbers.push_back(p.status == "ok" ? get(p) : kNaN);
    t.columns.push_back(std::move(c));
  };
  strings("id", [](const CohortPatient& p) { return p.id; });
  strings("pathology", [](const CohortPatient& p) { return p.pathology; });
  strings("status", [](const CohortPatient& p) { return p.status; });
  strings("rating", [](const CohortPatient& p) { return p.rating; });
  numbers("error_default_mm", "mm", [](const CohortPatient& p) { return p.error_default_mm; });
  numbers("error_default_sd_mm", "mm",
          [](const CohortPatient& p) { return p.error_default_sd_mm; });
  numbers("error_default_p95_mm", "mm",
          [](const CohortPatient& p) { return p.error_default_p95_mm; });
  numbers("error_calibrated_mm", "mm",
          [](const CohortPatient& p) { return p.error_calibrated_mm; });
  numbers("orifice_mm2", "mm^2", [](const CohortPatient& p) { return p.orifice_mm2; });
  numbers("orifice_observed_mm2", "mm^2",
          [](const CohortPatient& p) { return p.orifice_observed_mm2; });
  numbers("coaptation_mm", "mm", [](const CohortPatient& p) { return p.coaptation_mm; });
  if (o.calibrate) {
    numbers("simulations", "", [](const CohortPatient& p) { return double(p.simulations); });
    numbers("calibrate_s", "s", [](const CohortPatient& p) { return p.calibrate_s; });
    // Per fitted parameter: fitted value, truth (NaN for real patients), SD, identified (0/1).
    std::set<std::string> names;
    for (const auto& p : r.patients)
      for (const auto& [name, v] : p.fitted.items()) names.insert(name);
    auto field = [](const json& j, const std::string& name) {
      if (!j.contains(name)) return kNaN;
      const json& v = j[name];
      return v.is_number() ? v.get<double>() : v.is_boolean() ? double(v.get<bool>()) : kNaN;
    };
    for (const std::string& name : names)
      for (const char* what : {"fitted", "truth", "sd", "identified"}) {
        TableColumn c;
        c.name = std::string(what) + "_" + name;
        for (const auto& p : r.patients) {
          const json& src = std::string(what) == "fitted"  ? p.fitted
                            : std::string(what) == "truth" ? p.truth
                            : std::string(what) == "sd"    ? p.sd
                                                           : p.identified;
          c.numbers.push_back(field(src, name));
        }
        t.columns.push_back(std::move(c));
      }
  }
  write_table_file(folder.path("study.h5"), t);

  // Plots.
  const json& s = r.summary;
  auto mean_of = [](const json& st) { return detail::number_at(st, "mean"); };
  auto sd_of = [](const json& st) { return detail::number_at(st, "sd"); };
  {
    Plot pl;
    pl.title = "Point-to-mesh error per patient";
    pl.x_label = "patient";
    pl.y_label = "mean error, mm";
    PlotSeries d{"default parameters", {}, {}, false, true, {}},
        c{"calibrated", {}, {}, false, true, {}};
    for (const auto& p : r.patients) {
      pl.categories.push_back(std::to_string(p.index));
      d.y.push_back(p.status == "ok" ? p.error_default_mm : kNaN);
      c.y.push_back(p.error_calibrated_mm);
    }
    pl.series.push_back(d);
    if (o.calibrate) pl.series.push_back(c);
    pl.h_lines.push_back({1.49, "paper, default parameters: 1.49 mm"});
    pl.write_png(folder.path("errors_per_patient.png"));
  }
  {
    Plot pl;
    pl.title = "Error by pathology (mean and SD)";
    pl.y_label = "mean error, mm";
    PlotSeries d{"default parameters", {}, {}, false, true, {}},
        c{"calibrated", {}, {}, false, true, {}};
    for (const auto& [name, v] : s["by_pathology"].items()) {
      pl.categories.push_back(name.rfind("prolapse_", 0) == 0 ? name.substr(9) : name);
      d.y.push_back(mean_of(v["error_default_mm"]));
      d.y_error.push_back(sd_of(v["error_default_mm"]));
      c.y.push_back(mean_of(v["error_calibrated_mm"]));
      c.y_error.push_back(sd_of(v["error_calibrated_mm"]));
    }
    pl.series.push_back(d);
    if (o.calibrate) pl.series.push_back(c);
    pl.h_lines.push_back({1.49, "paper: 1.49 mm"});
    pl.write_png(folder.path("errors_by_pathology.png"));
  }
  {
    Plot pl;
    pl.title = "Closure ratings (share of patients)";
    pl.y_label = "% of patients";
    PlotSeries m{"mvtwin (automatic rating)", {}, {}, false, true, {}},
        p{"paper (visual rating, 25 patients)", {}, {}, false, true, {}};
    const double paper[] = {7, 9, 9};
    const double ok = s["overall"]["patients"].get<double>() - s["overall"]["failed"].get<double>();
    for (int k = 0; k < 3; ++k) {
      pl.categories.push_back(kRatings[k]);
      m.y.push_back(ok > 0 ? 100.0 * s["overall"]["ratings"][kRatings[k]].get<double>() / ok
                           : kNaN);
      p.y.push_back(100.0 * paper[k] / 25.0);
    }
    pl.series = {m, p};
    pl.write_png(folder.path("ratings.png"));
  }

  // The report.
  Report rep("Cohort study: closure with default and calibrated parameters");
  rep.paragraph("Compared with " + std::string(kPaperCitation) + " (its Tables 2 and 3).");
  const int np = static_cast<int>(r.patients.size());
  rep.paragraph(
      o.folder.empty()
          ? "**" + std::to_string(np) + " virtual patients (SYNTHETIC)** of cohort seed " +
                std::to_string(o.seed) +
                ", the pathologies in turn. Their observed closures were simulated by a finer "
                "model than the one compared (`" +
                std::to_string(o.observation.simulation.model.ures) + " x " +
                std::to_string(o.observation.simulation.model.vres) + "`, dt " +
                number(o.observation.simulation.dt, 4) + " s) with " +
                number(o.observation.noise_mm) + " mm detection-like noise."
          : std::to_string(np) + " patient files from `" + o.folder.string() + "`.");
  rep.paragraph(
      "Simulation model: " + std::to_string(o.model.model.ures) + " x " +
      std::to_string(o.model.model.vres) + " grid, " + std::to_string(o.model.model.layers) +
      " layer(s), dt " + number(o.model.dt, 4) +
      " s. Error: symmetric point-to-mesh distance "
      "between the simulated and the observed closed leaflets (annulus row excluded), mm. " +
      (o.calibrate
           ? "Calibration: " + o.fit + " by " + inverse::fit_method_name(o.method) + ", at most " +
                 std::to_string(o.max_simulations) + " simulations, searching with the " +
                 std::to_string(o.fit_model.model.ures) + " x " +
                 std::to_string(o.fit_model.model.vres) + " model (dt " +
                 number(o.fit_model.dt, 4) +
                 " s), then refined on the model above (its fit, the uncertainty's Jacobian and "
                 "two damped Gauss-Newton steps simulated there, the best kept), so that the "
                 "errors before and after are measured alike."
           : std::string("Not calibrated (default parameters only).")));
  rep.paragraph(
      "Closure rating (automatic, in place of the paper's visual one: was the observed closure "
      "captured?), from the effective regurgitant orifice (EROA, docs/regurgitant-orifice.md) of "
      "the simulated closed valve against the observed one (a virtual patient's: the closed valve "
      "of the model that made its observation): **satisfactory** within max(" +
      number(o.rating.match_mm2, 1) + " mm^2, " + number(100 * o.rating.match_fraction, 0) +
      " % of the observed); **passable** with the same MR grade (ASE 2017) or within twice that; "
      "**unsatisfactory** otherwise.");
  rep.heading("mvtwin next to the paper");
  const json& ov = s["overall"];
  auto cell = [&](const json& st) { return mean_sd(mean_of(st), sd_of(st)); };
  std::vector<std::vector<std::string>> rows;
  rows.push_back({"patients",
                  std::to_string(np) + " (" + std::to_string(ov["failed"].get<int>()) + " failed)",
                  "25"});
  rows.push_back({"error, default parameters, mm", cell(ov["error_default_mm"]), "1.49 ± 0.62"});
  const char* paper_rating[] = {"7 (1.07 ± 0.36)", "9 (1.38 ± 0.31)", "9 (1.91 ± 0.77)"};
  for (int k = 0; k < 3; ++k) {
    const json& br = s.contains("by_rating") && s["by_rating"].contains(kRatings[k])
                         ? s["by_rating"][kRatings[k]]
                         : json();
    rows.push_back({std::string(kRatings[k]) + ": patients (error, mm)",
                    std::to_string(ov["ratings"][kRatings[k]].get<int>()) +
                        (br.is_null() ? "" : " (" + cell(br["error_default_mm"]) + ")"),
                    paper_rating[k]});
  }
  if (o.calibrate)
    rows.push_back({"error, calibrated, mm", cell(ov["error_calibrated_mm"]),
                    "1.27, 1.12, 1.50 (3 patients, rest lengths by hand)"});
  rep.table({"", "mvtwin", "paper"}, rows);
  if (s.contains("observations")) {
    const json& ob = s["observations"];
    int retried = 0;
    std::string how;
    for (const auto& [setting, count] : ob["retried"].items()) {
      retried += count.get<int>();
      how += "; " + std::to_string(count.get<int>()) + " by " + setting;
    }
    if (retried + ob["lost"].get<int>() + ob["as_given"].get<int>() > 0)
      rep.paragraph("Observed closures: " + std::to_string(ob["as_given"].get<int>()) +
                    " by the observation model as given, " + std::to_string(retried) +
                    " by a safer retry after it failed (the same model stepped more carefully" +
                    how + "), " + std::to_string(ob["lost"].get<int>()) +
                    " lost (every setting failed; the patient's reason says why).");
  }
  rep.heading("Per pathology");
  rows.clear();
  for (const auto& [name, v] : s["by_pathology"].items())
    rows.push_back(
        {name, std::to_string(v["patients"].get<int>()), cell(v["error_default_mm"]),
         cell(v["error_default_p95_mm"]), o.calibrate ? cell(v["error_calibrated_mm"]) : "-",
         mean_sd(mean_of(v["orifice_mm2"]), sd_of(v["orifice_mm2"]), 1) + " (" +
             mean_sd(mean_of(v["orifice_observed_mm2"]), sd_of(v["orifice_observed_mm2"]), 1) + ")",
         std::to_string(v["ratings"]["satisfactory"].get<int>()) + " / " +
             std::to_string(v["ratings"]["passable"].get<int>()) + " / " +
             std::to_string(v["ratings"]["unsatisfactory"].get<int>())});
  rep.table(
      {"pathology", "patients", "error default, mm", "95th percentile, mm", "error calibrated, mm",
       "orifice simulated (observed), mm^2", "satisfactory / passable / unsatisfactory"},
      rows);
  rep.figure("errors_by_pathology.png",
             "Mean point-to-mesh error by pathology (bars: SD over patients).");
  rep.figure("ratings.png",
             "Closure ratings: mvtwin's automatic rating against the paper's visual one.");
  if (o.calibrate && s.contains("calibration")) {
    const json& cs = s["calibration"];
    rep.heading("Calibration");
    rows.clear();
    auto max_of = [](const json& st) { return detail::number_at(st, "max"); };
    rows.push_back({"patients calibrated", std::to_string(cs["calibrated"].get<int>())});
    rows.push_back({"simulations per patient",
                    mean_sd(mean_of(cs["simulations"]), sd_of(cs["simulations"]), 1) + " (max " +
                        number(max_of(cs["simulations"]), 0) + ", failed in all " +
                        std::to_string(cs["failed_simulations"].get<int>()) + ")"});
    rows.push_back({"wall time per calibration, s",
                    mean_sd(mean_of(cs["calibrate_s"]), sd_of(cs["calibrate_s"]), 1) + " (max " +
                        number(max_of(cs["calibrate_s"]), 1) + ")"});
    if (mean_of(cs["error_calibrated_over_noise"]) > 0)
      rows.push_back(
          {"error after / observation noise SD", cell(cs["error_calibrated_over_noise"])});
    rows.push_back({"noise SD estimated by the fit, mm", cell(cs["noise_fit_mm"])});
    const json& rr = cs["restlength_recovery"];
    if (rr["identified"].get<int>() + rr["unidentified"].get<int>() > 0)
      rows.push_back({"rest-length factors within " + number(rr["tolerance"].get<double>(), 2) +
                          " of the truth",
                      std::to_string(rr["identified_within_tolerance"].get<int>()) + " of " +
                          std::to_string(rr["identified"].get<int>()) + " identified (" +
                          std::to_string(rr["unidentified"].get<int>()) +
                          " not identified by the data)"});
    rep.table({"", std::string("mvtwin (") + inverse::fit_method_name(o.method) + ")"}, rows);
  }
  if (o.calibrate && !s["fitted_minus_truth_abs"].empty()) {
    rep.heading("Fitted parameters against the truth (virtual patients)");
    rep.paragraph(
        "Identified: the data determine the parameter (not along a null direction of the fit's "
        "J^T J, and its SD at most its scale); the others stay near where the search left them.");
    rows.clear();
    for (const auto& [name, v] : s["fitted_minus_truth_abs"].items()) {
      const json& vi = s["fitted_minus_truth_abs_identified"].contains(name)
                           ? s["fitted_minus_truth_abs_identified"][name]
                           : json();
      rows.push_back({name, std::to_string(v["n"].get<int>()), cell(v),
                      vi.is_null() ? "0" : std::to_string(vi["n"].get<int>()),
                      vi.is_null() ? "-" : cell(vi)});
    }
    rep.table({"parameter", "patients", "|fitted - truth|", "identified in",
               "|fitted - truth|, identified"},
              rows);
  }
  rep.heading("Per patient");
  rows.clear();
  for (const auto& p : r.patients)
    rows.push_back({std::to_string(p.index), p.id, p.pathology,
                    p.status == "ok" ? number(p.error_default_mm) : "failed",
                    p.status == "ok" ? number(p.error_default_p95_mm) : "-",
                    p.status == "ok"
                        ? number(p.orifice_mm2, 1) + " (" + number(p.orifice_observed_mm2, 1) + ")"
                        : "-",
                    p.status == "ok" ? number(p.coaptation_mm, 1) : "-",
                    p.rating.empty() ? "-" : p.rating, number(p.error_calibrated_mm)});
  rep.table({"#", "id", "pathology", "error, mm", "p95, mm", "orifice (observed), mm^2",
             "coaptation, mm", "rating", "calibrated, mm"},
            rows);
  rep.figure("errors_per_patient.png", "Point-to-mesh error per patient.");
  bool failures = false;
  for (const auto& p : r.patients)
    if (!p.reason.empty()) {
      if (!failures) rep.heading("Failures");
      failures = true;
      rep.paragraph("`" + p.id + "`: " + p.reason);
    }
  // Scaling: this run's per-patient work replayed on more ranks (dynamic balancing).
  std::vector<double> work;
  for (const auto& p : r.patients)
    if (p.status == "ok" && p.default_s + p.calibrate_s > 0)
      work.push_back(p.default_s + p.calibrate_s);
  if (work.size() >= 2) {
    rep.heading("Scaling over MPI ranks (expected)");
    const detail::Stats ws = detail::stats(work);
    rep.paragraph(
        "Per-patient work in this run (default simulation" +
        std::string(o.calibrate ? " and calibration" : "") + "): " + mean_sd(ws.mean, ws.sd, 1) +
        " s (min " + number(*std::min_element(work.begin(), work.end()), 1) + ", max " +
        number(*std::max_element(work.begin(), work.end()), 1) +
        "). Replaying cohorts drawn from these times on ranks that each take the next patient "
        "when free gives the parallel efficiency below (mean of 20 draws; 1 = no rank waits).");
    rows.clear();
    for (int ranks : {2, 10, 100, 1000}) {
      std::vector<std::string> row{std::to_string(ranks)};
      for (int n : {100, 1000, 10000})
        row.push_back(number(expected_efficiency(work, n, ranks), 3));
      rows.push_back(row);
    }
    rep.table({"ranks", "100 patients", "1,000 patients", "10,000 patients"}, rows);
  }
  rep.how_made(o.command, r.workers, r.wall_s);
  rep.write(folder.dir());
}

}  // namespace

}  // namespace mvtwin::studies
