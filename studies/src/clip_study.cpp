#include "mvtwin/studies/clip_study.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <memory>
#include <mutex>
#include <numeric>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/calibration_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/regurgitant_orifice.h"
#include "mvtwin/core/table_file.h"
#include "mvtwin/core/version.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/forward/chordae_tuning.h"
#include "mvtwin/forward/clip_device.h"
#include "mvtwin/inverse/clip_prediction.h"
#include "mvtwin/inverse/outcome_uncertainty.h"
#include "mvtwin/inverse/parameter_space.h"
#include "mvtwin/studies/cohort_study.h"
#include "mvtwin/studies/plot.h"
#include "mvtwin/studies/report.h"
#include "study_util.h"

namespace mvtwin::studies {
namespace fs = std::filesystem;
using detail::kNaN;
using detail::nullable;
using detail::number_at;
using nlohmann::json;

ClipStudyOptions::ClipStudyOptions()
    : observation(CohortStudyOptions::study_observation()),
      fit_model(CohortStudyOptions::default_fit_model()) {}

bool ClipStudyOptions::is_valid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = "clip study: " + m;
    return false;
  };
  if (out.empty()) return fail("no output folder (--out)");
  if (patients < 1) return fail("need at least one patient");
  if (max_scanned < patients) return fail("max_scanned must be at least the number of patients");
  if (!(min_eroa_mm2 >= 0)) return fail("the qualifying EROA must be >= 0 mm^2");
  if (jobs < 1 || jobs > 256) return fail("jobs must be 1 to 256");
  if (devices.empty()) return fail("no devices");
  for (const std::string& d : devices) {
    try {
      forward::clip_device(d);
    } catch (const std::exception& ex) {
      return fail(ex.what());
    }
  }
  if (positions.empty()) return fail("no clip positions");
  for (double p : positions)
    if (!(p > 0 && p < 1)) return fail("clip positions must be in (0, 1)");
  if (!(tolerance_mm2 > 0 && tolerance_fraction > 0 && mva_tolerance_fraction > 0))
    return fail("tolerances must be > 0");
  if (max_simulations < 1) return fail("max_simulations must be >= 1");
  if (!(observation.noise_mm >= 0)) return fail("observation noise must be >= 0 mm");
  std::string e;
  if (!model.is_valid(&e)) return fail(e);
  if (!fit_model.is_valid(&e)) return fail("search model: " + e);
  if (!observation.simulation.is_valid(&e)) return fail("observation model: " + e);
  if (!diastole.is_valid(&e)) return fail(e);
  try {
    inverse::ParameterSpace(fit, defaults);
  } catch (const std::exception& ex) {
    return fail(ex.what());
  }
  return true;
}

ClipStudyOptions ClipStudyOptions::quick() {
  ClipStudyOptions o;
  o.patients = 2;
  o.min_eroa_mm2 = 0.0;
  o.max_scanned = 4;
  o.observation.simulation = forward::ClosureOptions{};
  o.observation.simulation.model.ures = 20;
  o.observation.simulation.model.vres = 16;
  o.observation.simulation.dt = 0.01;
  o.observation.tune_normal_chordae = false;  // 13 closures at 30 x 30 per normal valve
  o.model.model.ures = 16;
  o.model.model.vres = 12;
  o.model.dt = 0.02;
  o.fit_model = o.model;
  o.fit = "restlength";
  o.max_simulations = 8;
  o.devices = {"XTW"};
  o.positions = {0.5};
  return o;
}

std::string ClipStudyOptions::option_device(int k) const {
  return devices[static_cast<std::size_t>(k) / positions.size()];
}
double ClipStudyOptions::option_position(int k) const {
  return positions[static_cast<std::size_t>(k) % positions.size()];
}

json ClipStudyOptions::config() const {
  json c{{"seed", seed},
         {"patients", patients},
         {"virtual_patient_edition", kVirtualPatientEdition},
         {"min_eroa_mm2", min_eroa_mm2},
         {"max_scanned", max_scanned},
         {"truth_model", detail::describe(observation.simulation)},
         {"observation_noise_mm", observation.noise_mm},
         {"normal_chordae_tuning",
          observation.tune_normal_chordae ? json(forward::kChordaeTuningEdition) : json(nullptr)},
         {"prediction_model", detail::describe(model)},
         {"search_model", detail::describe(fit_model)},
         {"defaults", detail::parameters_json(defaults)},
         {"fit", fit},
         {"method", inverse::fit_method_name(method)},
         {"max_simulations", max_simulations},
         {"devices", devices},
         {"positions", positions},
         {"diastole",
          {{"transmitral_mmhg", diastole.transmitral_mmhg},
           {"stroke_volume_ml", diastole.stroke_volume_ml},
           {"filling_time_s", diastole.filling_time_s}}},
         {"intervals", intervals},
         // The intervals' mesh part (a folder made before it is refused, not mixed).
         {"interval_mesh_factor", intervals ? json(inverse::MeshCheck{}.factor) : json(nullptr)}};
  detail::add_calibration_scans(&c, fit);
  return c;
}

json ClipStudyOption::to_json() const {
  return {{"device", device},
          {"positions", positions},
          {"eroa_true_mm2", nullable(eroa_true_mm2)},
          {"eroa_predicted_mm2", nullable(eroa_predicted_mm2)},
          {"eroa_predicted_sd_mm2", nullable(eroa_predicted_sd_mm2)},
          {"eroa_default_mm2", nullable(eroa_default_mm2)},
          {"mva_true_cm2", nullable(mva_true_cm2)},
          {"mva_predicted_cm2", nullable(mva_predicted_cm2)},
          {"gradient_true_mmhg", nullable(gradient_true_mmhg)},
          {"gradient_predicted_mmhg", nullable(gradient_predicted_mmhg)},
          {"stenosis_true", stenosis_true},
          {"stenosis_predicted", stenosis_predicted},
          {"min_insertion_predicted_mm", nullable(min_insertion_predicted_mm)},
          {"detachment_risk_predicted", detachment_risk_predicted},
          {"rank_true", rank_true},
          {"rank_predicted", rank_predicted},
          {"truth_reason", truth_reason},
          {"prediction_reason", prediction_reason},
          {"truth_s", truth_s}};
}

namespace {

std::string option_text(const std::string& device, double position) {
  return device + " at " + number(position, 2);
}

/// The truth inside the prediction's 95 % interval.
bool inside_95(double predicted, double sd, double truth) {
  return std::abs(truth - predicted) <= inverse::kZ95 * sd;
}

bool within(double predicted, double truth, double abs_tol, double rel_tol) {
  return std::isfinite(predicted) && std::isfinite(truth) &&
         std::abs(predicted - truth) <= std::max(abs_tol, rel_tol * std::abs(truth));
}

/// Ranks (1 = smallest) of the finite values; 0 for the others.
std::vector<int> ranks_of(const std::vector<double>& v) {
  std::vector<int> idx(v.size());
  std::iota(idx.begin(), idx.end(), 0);
  std::stable_sort(idx.begin(), idx.end(), [&](int a, int b) {
    const bool fa = std::isfinite(v[static_cast<std::size_t>(a)]),
               fb = std::isfinite(v[static_cast<std::size_t>(b)]);
    if (fa != fb) return fa;
    return fa && v[static_cast<std::size_t>(a)] < v[static_cast<std::size_t>(b)];
  });
  std::vector<int> rank(v.size(), 0);
  int r = 0;
  for (int i : idx)
    if (std::isfinite(v[static_cast<std::size_t>(i)])) rank[static_cast<std::size_t>(i)] = ++r;
  return rank;
}

double eroa_of(const inverse::ClosureQuality& q) { return q.converged ? q.orifice.eroa_mm2 : kNaN; }

void write_outputs(const ClipStudyOptions& o, const ClipStudyResult& r, const StudyFolder& f);

}  // namespace

json ClipStudyPatient::to_json() const {
  auto option_ref = [&](int k) {
    if (k < 0) return json(nullptr);
    const ClipStudyOption& op = options[static_cast<std::size_t>(k)];
    return json{{"device", op.device}, {"positions", op.positions}, {"index", k}};
  };
  json opts = json::array();
  for (const auto& op : options) opts.push_back(op.to_json());
  return {{"index", index},
          {"id", id},
          {"pathology", pathology},
          {"synthetic", true},
          {"status", status},
          {"reason", reason},
          {"eroa_no_clip_true_mm2", nullable(eroa_no_clip_true_mm2)},
          {"eroa_no_clip_predicted_mm2", nullable(eroa_no_clip_predicted_mm2)},
          {"eroa_no_clip_predicted_sd_mm2", nullable(eroa_no_clip_predicted_sd_mm2)},
          {"eroa_no_clip_default_mm2", nullable(eroa_no_clip_default_mm2)},
          {"error_before_mm", nullable(error_before_mm)},
          {"error_after_mm", nullable(error_after_mm)},
          {"fitted", fitted},
          {"truth", truth},
          {"calibrate_s", calibrate_s},
          {"predict_s", predict_s},
          {"best_true", option_ref(best_true)},
          {"best_predicted", option_ref(best_predicted)},
          {"best_default", option_ref(best_default)},
          {"options", opts}};
}

ClipStudyResult run_clip_study(const ClipStudyOptions& o, WorkPool& pool) {
  std::string err;
  if (!o.is_valid(&err)) throw Error(err);
  const auto t0 = std::chrono::steady_clock::now();
  const std::unique_ptr<StudyFolder> folder =
      open_study_folder(pool, o.out, "clip-prediction", o.config());
  const fs::path cache = o.cache.empty() ? o.out / "observed" : o.cache;
  const fs::path calibrations = o.out / "calibrations";
  if (pool.is_root()) {
    create_output_directory(cache);
    create_output_directory(calibrations);
  }
  pool.barrier();

  std::mutex progress_mutex;
  auto report = [&](const std::string& stage, int done, int total, const std::string& msg) {
    if (!o.progress) return;
    std::lock_guard<std::mutex> lock(progress_mutex);
    o.progress({stage, done, total, msg});
  };
  auto load = [&](const fs::path& file) {
    std::lock_guard<std::mutex> lock(hdf5_mutex());
    return read_patient(file, false);
  };
  auto file_of = [&](const json& member) {
    return detail::observed_file(cache, cohort_member(o.seed, member.at("index").get<int>()),
                                 o.observation);
  };

  // Stage 1: the cohort's members observed in order (the fine model's closure is the truth
  // without a clip) until enough qualify.
  ClipStudyResult res;
  std::vector<json> qualified;
  std::atomic<int> done{0};
  for (int next = 0; static_cast<int>(qualified.size()) < o.patients && next < o.max_scanned;) {
    const int need = o.patients - static_cast<int>(qualified.size());
    const int batch = std::min(o.max_scanned - next, std::max(need, o.jobs * pool.size()));
    const auto out = pool.map(batch, o.jobs, [&](int b) -> std::string {
      const int i = next + b;
      char name[32];
      std::snprintf(name, sizeof name, "member_%04d", i);
      if (auto rec = folder->record(name)) {
        report("observe", ++done, o.max_scanned, std::string(name) + ": done before (resumed)");
        return rec->dump();
      }
      const CohortMember m = cohort_member(o.seed, i);
      json r{{"index", i},
             {"id", m.id},
             {"pathology", std::string(pathology_name(m.pathology))},
             {"observe_s", 0.0}};
      try {
        report("observe", done, o.max_scanned, m.id + ": its observed closure (fine model)");
        const fs::path file = file_of(r);
        r["observe_s"] = detail::ensure_observed(file, o.seed, i, o.observation);
        const Patient p = load(file);
        if (!p.truth || !p.truth->closed_orifice)
          throw Error(file.string() + " holds no observed regurgitant orifice");
        r["eroa_true_mm2"] = p.truth->closed_orifice->eroa_mm2;
        r["observed_with"] = p.truth->observed_with.empty() ? "as given" : p.truth->observed_with;
      } catch (const std::exception& ex) {
        r["reason"] = std::string("observation failed: ") + ex.what();
      }
      folder->save_record(name, r);
      report("observe", ++done, o.max_scanned,
             m.id + " (" + r["pathology"].get<std::string>() + "): " +
                 (r.contains("reason")
                      ? r["reason"].get<std::string>()
                      : "EROA " + number(r["eroa_true_mm2"].get<double>(), 1) + " mm^2"));
      return r.dump();
    });
    for (const std::string& s : out) {
      const json r = json::parse(s);
      res.scanned.push_back(r);
      if (static_cast<int>(qualified.size()) < o.patients && !r.contains("reason") &&
          r.at("eroa_true_mm2").get<double>() >= o.min_eroa_mm2)
        qualified.push_back(r);
    }
    next += batch;
  }

  // Stage 2: per patient one prediction item (calibrate, then every option on the calibrated
  // and on the default parameters), and one truth item per option (the fine model).
  const int np = static_cast<int>(qualified.size()), K = o.num_options();
  auto sites_of = [&](int k) {
    inverse::ClipSite s;
    s.device = o.option_device(k);
    s.position = o.option_position(k);
    return std::vector<inverse::ClipSite>{s};
  };
  done = 0;
  const int n = np * (1 + K);
  const auto items = pool.map(n, o.jobs, [&](int item) -> std::string {
    const bool predict = item < np;
    const int pi = predict ? item : (item - np) / K, k = predict ? -1 : (item - np) % K;
    const json& member = qualified[static_cast<std::size_t>(pi)];
    const int index = member.at("index").get<int>();
    char name[48];
    if (predict)
      std::snprintf(name, sizeof name, "patient_%04d_predicted", index);
    else
      std::snprintf(name, sizeof name, "patient_%04d_true_%d", index, k);
    if (auto rec = folder->record(name)) {
      report("simulate", ++done, n, std::string(name) + ": done before (resumed)");
      return rec->dump();
    }
    // What made the record (a study resumed over sessions may span several commits).
    json r{{"index", index}, {"mvtwin_version", kVersion}};
    try {
      // A study resumed from its records alone (on another machine, or with its observation
      // cache removed) makes again the observations that its unfinished items need (only when
      // missing: ensure_observed would read an existing file once more before load does).
      const fs::path observed = file_of(member);
      if (!fs::exists(observed)) detail::ensure_observed(observed, o.seed, index, o.observation);
      const Patient p = load(observed);
      if (!predict) {
        const auto t = std::chrono::steady_clock::now();
        std::vector<inverse::ClipScenario> s = inverse::simulate_clips(
            p, p.truth->parameters, o.observation.simulation, {sites_of(k)}, 1);
        inverse::open_clips(p, p.truth->parameters, o.observation.simulation, o.diastole, 1, 1, &s);
        r["eroa_mm2"] = nullable(eroa_of(s[0].quality));
        r["reason"] = s[0].quality.converged ? "" : s[0].quality.reason;
        const inverse::ClipOpening& op = s[0].opening;
        r["mva_cm2"] = nullable(op.converged ? op.mva_cm2 : kNaN);
        r["gradient_mmhg"] = nullable(op.converged ? op.gradient_mmhg : kNaN);
        r["stenosis"] = op.converged && op.stenosis;
        if (!op.converged && s[0].quality.converged) r["diastole_reason"] = op.reason;
        r["s"] = detail::seconds_since(t);
      } else {
        // The calibration from the noisy observed frames, kept beside the study.
        const fs::path calfile = calibrations / (p.id + ".h5");
        const auto t = std::chrono::steady_clock::now();
        inverse::ObjectiveOptions oo;
        oo.simulation = o.model;
        inverse::ClosureObjective obj(p, inverse::ParameterSpace(o.fit, o.defaults), oo);
        inverse::CalibrationOptions co;
        co.method = o.method;
        co.jobs = 1;
        co.max_simulations = o.max_simulations;
        co.search_model = o.fit_model;
        const inverse::CalibrationResult cr = inverse::calibrate(obj, co);
        const CalibrationRecord rec = inverse::make_calibration_record(cr, p, o.model, co);
        {
          std::lock_guard<std::mutex> lock(hdf5_mutex());
          write_calibration_file(calfile, rec);
        }
        r["calibrate_s"] = detail::seconds_since(t);
        r["error_before_mm"] = cr.error_before_mm;
        r["error_after_mm"] = cr.error_after_mm;
        json fitted = json::object(), truth = json::object();
        const Eigen::VectorXd tv = obj.space().values_of(p.truth->parameters);
        for (int j = 0; j < obj.space().size(); ++j) {
          fitted[obj.space().specs()[static_cast<std::size_t>(j)].name] = cr.fitted[j];
          truth[obj.space().specs()[static_cast<std::size_t>(j)].name] = tv[j];
        }
        r["fitted"] = fitted;
        r["truth"] = truth;
        // The options on the calibrated parameters (with intervals) and on the defaults.
        const auto t2 = std::chrono::steady_clock::now();
        std::vector<std::vector<inverse::ClipSite>> cands{{}};
        for (int j = 0; j < K; ++j) cands.push_back(sites_of(j));
        const ValveParameters& par = rec.parameters;
        std::vector<inverse::ClipScenario> pred =
            inverse::simulate_clips(p, par, o.model, cands, 1);
        inverse::open_clips(p, par, o.model, o.diastole, pred.size(), 1, &pred);
        inverse::CalibrationPosterior post = inverse::posterior_of(rec);
        r["intervals"] = o.intervals && post.usable;
        r["intervals_why_not"] = !o.intervals ? "not asked for" : post.why_not;
        if (o.intervals && post.usable)
          inverse::propagate_clip_uncertainty(p, post, o.model, o.diastole, pred[0].quality,
                                              pred.size(), 1, &pred);
        const std::vector<inverse::ClipScenario> def =
            inverse::simulate_clips(p, o.defaults, o.model, cands, 1);
        json sc = json::array();
        for (std::size_t j = 0; j < pred.size(); ++j) {
          const inverse::ClipScenario& s = pred[j];
          const inverse::ClipUncertainty& u = s.uncertainty;
          const double sd = u.computed ? u.sd[0] : kNaN;
          const inverse::ClipFlags fl = inverse::clip_flags(s.quality.clip_grasps);
          sc.push_back(
              {{"eroa_mm2", nullable(eroa_of(s.quality))},
               {"eroa_sd_mm2", nullable(sd)},
               {"eroa_sd_parameters_mm2", nullable(u.computed ? u.sd_parameters[0] : kNaN)},
               {"eroa_refined_mm2", nullable(u.computed ? u.at_refined[0] : kNaN)},
               {"reason", s.quality.converged ? "" : s.quality.reason},
               {"mva_cm2", nullable(s.opening.converged ? s.opening.mva_cm2 : kNaN)},
               {"gradient_mmhg", nullable(s.opening.converged ? s.opening.gradient_mmhg : kNaN)},
               {"stenosis", s.opening.converged && s.opening.stenosis},
               {"diastole_reason", s.opening.converged ? "" : s.opening.reason},
               {"min_insertion_mm", fl.min_insertion_mm},
               {"detachment_risk", fl.detachment_risk},
               {"eroa_default_mm2", nullable(eroa_of(def[j].quality))}});
        }
        r["scenarios"] = sc;
        r["predict_s"] = detail::seconds_since(t2);
      }
    } catch (const std::exception& ex) {
      r["failed"] = ex.what();
    }
    folder->save_record(name, r);
    std::string msg = std::string(name) + ": ";
    if (r.contains("failed"))
      msg += "failed: " + r["failed"].get<std::string>();
    else if (predict)
      msg += "calibrated " + number(r["error_before_mm"].get<double>()) + " -> " +
             number(r["error_after_mm"].get<double>()) + " mm, options predicted";
    else
      msg += option_text(o.option_device(k), o.option_position(k)) + ": true EROA " +
             (r["eroa_mm2"].is_number() ? number(r["eroa_mm2"].get<double>(), 1) + " mm^2"
                                        : "failed (" + r["reason"].get<std::string>() + ")");
    report("simulate", ++done, n, msg);
    return r.dump();
  });

  // Assemble.
  for (int pi = 0; pi < np; ++pi) {
    const json& member = qualified[static_cast<std::size_t>(pi)];
    ClipStudyPatient cp;
    cp.index = member.at("index");
    cp.id = member.at("id");
    cp.pathology = member.at("pathology");
    cp.eroa_no_clip_true_mm2 = member.at("eroa_true_mm2");
    const json pr = json::parse(items[static_cast<std::size_t>(pi)]);
    const bool pred_ok = !pr.contains("failed");
    if (!pred_ok) {
      cp.status = "failed";
      cp.reason = "calibration or prediction failed: " + pr["failed"].get<std::string>();
    }
    auto scen = [&](int j) -> json {
      return pred_ok ? pr.at("scenarios").at(static_cast<std::size_t>(j)) : json::object();
    };
    cp.eroa_no_clip_predicted_mm2 = number_at(scen(0), "eroa_mm2");
    cp.eroa_no_clip_predicted_sd_mm2 = number_at(scen(0), "eroa_sd_mm2");
    cp.eroa_no_clip_default_mm2 = number_at(scen(0), "eroa_default_mm2");
    cp.error_before_mm = number_at(pr, "error_before_mm");
    cp.error_after_mm = number_at(pr, "error_after_mm");
    cp.fitted = pr.value("fitted", json::object());
    cp.truth = pr.value("truth", json::object());
    cp.calibrate_s = pr.value("calibrate_s", 0.0);
    cp.predict_s = pr.value("predict_s", 0.0);
    std::vector<double> vt, vp, vd;
    for (int k = 0; k < K; ++k) {
      const json tr = json::parse(items[static_cast<std::size_t>(np + pi * K + k)]);
      const json ps = scen(k + 1);
      ClipStudyOption op;
      op.device = o.option_device(k);
      op.positions = {o.option_position(k)};
      op.eroa_true_mm2 = number_at(tr, "eroa_mm2");
      op.mva_true_cm2 = number_at(tr, "mva_cm2");
      op.gradient_true_mmhg = number_at(tr, "gradient_mmhg");
      op.stenosis_true = tr.value("stenosis", false);
      op.truth_reason = tr.contains("failed") ? tr["failed"].get<std::string>()
                                              : tr.value("reason", std::string());
      op.truth_s = tr.value("s", 0.0);
      op.eroa_predicted_mm2 = number_at(ps, "eroa_mm2");
      op.eroa_predicted_sd_mm2 = number_at(ps, "eroa_sd_mm2");
      op.eroa_default_mm2 = number_at(ps, "eroa_default_mm2");
      op.mva_predicted_cm2 = number_at(ps, "mva_cm2");
      op.gradient_predicted_mmhg = number_at(ps, "gradient_mmhg");
      op.stenosis_predicted = ps.value("stenosis", false);
      op.min_insertion_predicted_mm = number_at(ps, "min_insertion_mm");
      op.detachment_risk_predicted = ps.value("detachment_risk", false);
      op.prediction_reason = pred_ok ? ps.value("reason", std::string()) : cp.reason;
      // Systole converged but the valve did not open: say so (MVA and gradient stay empty).
      auto diastole = [](const json& j, std::string* reason) {
        const std::string d = j.value("diastole_reason", std::string());
        if (reason->empty() && !d.empty()) *reason = "diastole failed: " + d;
      };
      diastole(tr, &op.truth_reason);
      diastole(ps, &op.prediction_reason);
      vt.push_back(op.eroa_true_mm2);
      vp.push_back(op.eroa_predicted_mm2);
      vd.push_back(op.eroa_default_mm2);
      cp.options.push_back(op);
    }
    const std::vector<int> rt = ranks_of(vt), rp = ranks_of(vp), rd = ranks_of(vd);
    for (int k = 0; k < K; ++k) {
      cp.options[static_cast<std::size_t>(k)].rank_true = rt[static_cast<std::size_t>(k)];
      cp.options[static_cast<std::size_t>(k)].rank_predicted = rp[static_cast<std::size_t>(k)];
      if (rt[static_cast<std::size_t>(k)] == 1) cp.best_true = k;
      if (rp[static_cast<std::size_t>(k)] == 1) cp.best_predicted = k;
      if (rd[static_cast<std::size_t>(k)] == 1) cp.best_default = k;
    }
    res.patients.push_back(std::move(cp));
  }

  // Summary against issue 39's targets.
  int n_eroa = 0, in_eroa = 0, in_eroa_default = 0, n_mva = 0, in_mva = 0, n_best = 0,
      best_top2 = 0, best_top2_default = 0, n_interval = 0, in_interval = 0, n_interval_all = 0,
      in_interval_all = 0, failed_truth = 0, failed_prediction = 0, failed_patients = 0;
  std::vector<double> err_cal, err_def, err_mva;
  auto count_eroa = [&](double pred, double def, double truth) {
    if (!std::isfinite(truth) || !std::isfinite(pred) || !std::isfinite(def)) return;
    ++n_eroa;
    in_eroa += within(pred, truth, o.tolerance_mm2, o.tolerance_fraction) ? 1 : 0;
    in_eroa_default += within(def, truth, o.tolerance_mm2, o.tolerance_fraction) ? 1 : 0;
    err_cal.push_back(std::abs(pred - truth));
    err_def.push_back(std::abs(def - truth));
  };
  for (const ClipStudyPatient& p : res.patients) {
    if (p.status != "ok") ++failed_patients;
    count_eroa(p.eroa_no_clip_predicted_mm2, p.eroa_no_clip_default_mm2, p.eroa_no_clip_true_mm2);
    for (const ClipStudyOption& op : p.options) {
      failed_truth += std::isfinite(op.eroa_true_mm2) ? 0 : 1;
      failed_prediction += std::isfinite(op.eroa_predicted_mm2) ? 0 : 1;
      count_eroa(op.eroa_predicted_mm2, op.eroa_default_mm2, op.eroa_true_mm2);
      if (std::isfinite(op.mva_true_cm2) && std::isfinite(op.mva_predicted_cm2)) {
        ++n_mva;
        in_mva += within(op.mva_predicted_cm2, op.mva_true_cm2, 0.0, o.mva_tolerance_fraction);
        err_mva.push_back(std::abs(op.mva_predicted_cm2 - op.mva_true_cm2) / op.mva_true_cm2);
      }
      if (std::isfinite(op.eroa_predicted_sd_mm2) && std::isfinite(op.eroa_true_mm2)) {
        ++n_interval_all;
        in_interval_all +=
            inside_95(op.eroa_predicted_mm2, op.eroa_predicted_sd_mm2, op.eroa_true_mm2);
      }
    }
    if (p.best_true >= 0 && p.best_predicted >= 0) {
      ++n_best;
      const int r = p.options[static_cast<std::size_t>(p.best_true)].rank_predicted;
      best_top2 += r >= 1 && r <= 2 ? 1 : 0;
      // The defaults' ranking of the truth's best option.
      std::vector<double> vd;
      for (const auto& op : p.options) vd.push_back(op.eroa_default_mm2);
      const int rd = ranks_of(vd)[static_cast<std::size_t>(p.best_true)];
      best_top2_default += rd >= 1 && rd <= 2 ? 1 : 0;
      const ClipStudyOption& b = p.options[static_cast<std::size_t>(p.best_predicted)];
      if (std::isfinite(b.eroa_predicted_sd_mm2) && std::isfinite(b.eroa_true_mm2)) {
        ++n_interval;
        in_interval += inside_95(b.eroa_predicted_mm2, b.eroa_predicted_sd_mm2, b.eroa_true_mm2);
      }
    }
  }
  auto frac = [](int a, int b) { return b > 0 ? json(static_cast<double>(a) / b) : json(nullptr); };
  const detail::Stats ec = detail::stats(err_cal), ed = detail::stats(err_def),
                      em = detail::stats(err_mva);
  res.summary = {
      {"patients", res.patients.size()},
      {"patients_failed", failed_patients},
      {"scanned", res.scanned.size()},
      {"truth_options_failed", failed_truth},
      {"predicted_options_failed", failed_prediction},
      {"eroa_compared", n_eroa},
      {"eroa_within_tolerance", in_eroa},
      {"eroa_within_tolerance_fraction", frac(in_eroa, n_eroa)},
      {"eroa_default_within_tolerance", in_eroa_default},
      {"eroa_default_within_tolerance_fraction", frac(in_eroa_default, n_eroa)},
      {"eroa_mean_abs_error_mm2", nullable(ec.mean)},
      {"eroa_default_mean_abs_error_mm2", nullable(ed.mean)},
      {"mva_compared", n_mva},
      {"mva_within_tolerance", in_mva},
      {"mva_within_tolerance_fraction", frac(in_mva, n_mva)},
      {"mva_mean_relative_error", nullable(em.mean)},
      {"patients_ranked", n_best},
      {"best_true_in_predicted_top2", best_top2},
      {"best_true_in_default_top2", best_top2_default},
      {"truth_in_best_interval", in_interval},
      {"best_intervals", n_interval},
      {"truth_in_interval", in_interval_all},
      {"intervals", n_interval_all},
      {"targets",
       {{"eroa_within_tolerance_fraction", 0.8},
        {"mva_within_tolerance_fraction", 1.0},
        {"best_true_in_predicted_top2", "8 of 10"},
        {"truth_in_best_interval", "8 of 10"},
        {"calibrated_beats_default", true}}},
      {"calibrated_beats_default",
       std::isfinite(ec.mean) && std::isfinite(ed.mean) ? json(ec.mean < ed.mean) : json(nullptr)}};
  res.workers = pool.describe();
  res.wall_s = detail::seconds_since(t0);
  if (pool.is_root()) write_outputs(o, res, *folder);
  pool.barrier();
  return res;
}

namespace {

std::string cell(double v, int digits = 1) { return std::isfinite(v) ? number(v, digits) : "-"; }
std::string yes_no(bool b) { return b ? "yes" : "no"; }
std::string inside_interval(double predicted, double sd, double truth) {
  if (!std::isfinite(predicted) || !std::isfinite(sd) || !std::isfinite(truth)) return "-";
  return yes_no(inside_95(predicted, sd, truth));
}

void write_outputs(const ClipStudyOptions& o, const ClipStudyResult& r, const StudyFolder& f) {
  json patients = json::array();
  for (const auto& p : r.patients) patients.push_back(p.to_json());
  json prov = detail::provenance(o.command, r.workers, r.wall_s);
  prov["seed"] = o.seed;
  write_json(f.path("study.json"), {{"format", "mvtwin-clip-study"},
                                    {"study", "clip-prediction"},
                                    {"synthetic", true},
                                    {"config", o.config()},
                                    {"provenance", prov},
                                    {"summary", r.summary},
                                    {"scanned", r.scanned},
                                    {"patients", patients}});
  TableFile t;
  t.format = "mvtwin-clip-study";
  t.attributes = {
      {"mvtwin_version", kVersion}, {"command", o.command}, {"config", o.config().dump()}};
  TableColumn id{"patient", "", {}, {}}, path{"pathology", "", {}, {}},
      option{"option", "", {}, {}}, et{"eroa_true_mm2", "mm^2", {}, {}},
      ep{"eroa_predicted_mm2", "mm^2", {}, {}}, es{"eroa_predicted_sd_mm2", "mm^2", {}, {}},
      ed{"eroa_default_mm2", "mm^2", {}, {}}, mt{"mva_true_cm2", "cm^2", {}, {}},
      mp{"mva_predicted_cm2", "cm^2", {}, {}}, gp{"gradient_predicted_mmhg", "mmHg", {}, {}},
      rt{"rank_true", "", {}, {}}, rp{"rank_predicted", "", {}, {}};
  for (const auto& p : r.patients) {
    auto row = [&](const std::string& name, double vt, double vp, double vs, double vd, double vmt,
                   double vmp, double vg, int r_t, int r_p) {
      id.strings.push_back(p.id);
      path.strings.push_back(p.pathology);
      option.strings.push_back(name);
      et.numbers.push_back(vt);
      ep.numbers.push_back(vp);
      es.numbers.push_back(vs);
      ed.numbers.push_back(vd);
      mt.numbers.push_back(vmt);
      mp.numbers.push_back(vmp);
      gp.numbers.push_back(vg);
      rt.numbers.push_back(r_t);
      rp.numbers.push_back(r_p);
    };
    row("no clip", p.eroa_no_clip_true_mm2, p.eroa_no_clip_predicted_mm2,
        p.eroa_no_clip_predicted_sd_mm2, p.eroa_no_clip_default_mm2, kNaN, kNaN, kNaN, 0, 0);
    for (const auto& op : p.options)
      row(option_text(op.device, op.positions.at(0)), op.eroa_true_mm2, op.eroa_predicted_mm2,
          op.eroa_predicted_sd_mm2, op.eroa_default_mm2, op.mva_true_cm2, op.mva_predicted_cm2,
          op.gradient_predicted_mmhg, op.rank_true, op.rank_predicted);
  }
  t.columns = {id, path, option, et, ep, es, ed, mt, mp, gp, rt, rp};
  write_table_file(f.path("study.h5"), t);

  const json& s = r.summary;
  auto count = [&](const char* a, const char* b) {
    return std::to_string(s.at(a).get<int>()) + " of " + std::to_string(s.at(b).get<int>());
  };
  Report rep("Clip study: the plan made on a calibrated patient against the truth");
  rep.paragraph(
      "Is a clip plan worth anything when it is made, as the pipeline makes it, on a model "
      "calibrated from noisy images? Patients: the first " +
      std::to_string(o.patients) + " SYNTHETIC virtual patients of cohort seed " +
      std::to_string(o.seed) + " whose true effective regurgitant orifice (EROA) is at least " +
      number(o.min_eroa_mm2, 0) + " mm^2 (" + std::to_string(r.scanned.size()) +
      " members looked at). **Truth**: each option simulated with the patient's hidden parameters "
      "on the fine model that made its observation (" +
      std::to_string(o.observation.simulation.model.ures) + " x " +
      std::to_string(o.observation.simulation.model.vres) + ", " +
      std::to_string(o.observation.simulation.model.layers) + " layer(s), dt " +
      number(o.observation.simulation.dt, 4) +
      " s), the EROA without a clip from its observed closure. **Prediction**: the same option "
      "on the model calibrated from the observed frames (" +
      number(o.observation.noise_mm) + " mm detection-like noise; fit " + o.fit + ", at most " +
      std::to_string(o.max_simulations) + " simulations, on " + std::to_string(o.model.model.ures) +
      " x " + std::to_string(o.model.model.vres) + ", dt " + number(o.model.dt, 4) +
      " s), which sees what images would show (the anatomy, torn chordae included) and never "
      "the hidden parameters; 95 % intervals from the calibration's covariance (one simulation "
      "one SD along each direction it determines). **Default**: the same option at the default "
      "parameters. Options: each of " +
      std::to_string(o.devices.size()) + " device(s) at " + std::to_string(o.positions.size()) +
      " positions along the coaptation line (0 = anterolateral commissure, 1 = posteromedial). "
      "Diastole: " +
      number(o.diastole.transmitral_mmhg, 1) +
      " mmHg; MVA from the open orifices, mean gradient "
      "by Gorlin (37.7) for " +
      number(o.diastole.stroke_volume_ml, 0) + " mL over " + number(o.diastole.filling_time_s, 2) +
      " s.");
  rep.heading("Against the targets of issue 39");
  rep.table(
      {"measure", "calibrated", "default parameters", "target"},
      {{"EROA within max(" + number(o.tolerance_mm2, 0) + " mm^2, " +
            number(100 * o.tolerance_fraction, 0) + " %) of the truth (no clip and each option)",
        count("eroa_within_tolerance", "eroa_compared"),
        count("eroa_default_within_tolerance", "eroa_compared"), ">= 80 %"},
       {"mean absolute EROA error, mm^2", cell(number_at(s, "eroa_mean_abs_error_mm2")),
        cell(number_at(s, "eroa_default_mean_abs_error_mm2")), "calibrated < default"},
       {"MVA within " + number(100 * o.mva_tolerance_fraction, 0) + " %",
        count("mva_within_tolerance", "mva_compared"), "-", "every option"},
       {"the truth's best option in the predicted top two",
        count("best_true_in_predicted_top2", "patients_ranked"),
        count("best_true_in_default_top2", "patients_ranked"), ">= 8 of 10"},
       {"the truth inside the best option's 95 % interval",
        count("truth_in_best_interval", "best_intervals"), "-", ">= 8 of 10"},
       {"the truth inside the 95 % interval, every option", count("truth_in_interval", "intervals"),
        "-", "-"}});
  rep.heading("Per patient");
  std::vector<std::vector<std::string>> rows;
  for (const auto& p : r.patients) {
    auto best = [&](int k) {
      return k < 0 ? std::string("-")
                   : option_text(p.options[static_cast<std::size_t>(k)].device,
                                 p.options[static_cast<std::size_t>(k)].positions.at(0));
    };
    rows.push_back(
        {p.id, p.pathology,
         cell(p.eroa_no_clip_true_mm2) + " / " + cell(p.eroa_no_clip_predicted_mm2) + " ± " +
             cell(inverse::kZ95 * p.eroa_no_clip_predicted_sd_mm2) + " / " +
             cell(p.eroa_no_clip_default_mm2),
         cell(p.error_before_mm, 2) + " → " + cell(p.error_after_mm, 2), best(p.best_true),
         best(p.best_predicted),
         p.best_true >= 0 && p.options[static_cast<std::size_t>(p.best_true)].rank_predicted > 0
             ? std::to_string(p.options[static_cast<std::size_t>(p.best_true)].rank_predicted)
             : "-",
         p.status == "ok" ? "" : p.reason});
  }
  rep.table({"patient", "pathology", "EROA no clip: true / predicted ± 95 % / default, mm^2",
             "fit error, mm", "truth's best", "predicted best", "truth's best ranked (prediction)",
             "failed"},
            rows);
  rep.heading("Every option");
  rows.clear();
  for (const auto& p : r.patients)
    for (const auto& op : p.options)
      rows.push_back(
          {p.id, option_text(op.device, op.positions.at(0)), cell(op.eroa_true_mm2),
           cell(op.eroa_predicted_mm2) + " ± " + cell(inverse::kZ95 * op.eroa_predicted_sd_mm2),
           cell(op.eroa_default_mm2),
           inside_interval(op.eroa_predicted_mm2, op.eroa_predicted_sd_mm2, op.eroa_true_mm2),
           cell(op.mva_true_cm2, 2) + " / " + cell(op.mva_predicted_cm2, 2),
           cell(op.gradient_true_mmhg) + " / " + cell(op.gradient_predicted_mmhg),
           yes_no(op.stenosis_true) + " / " + yes_no(op.stenosis_predicted),
           std::to_string(op.rank_true) + " / " + std::to_string(op.rank_predicted),
           op.truth_reason.empty() ? op.prediction_reason : op.truth_reason});
  rep.table({"patient", "option", "EROA true, mm^2", "predicted ± 95 %", "default",
             "truth inside 95 %", "MVA true / predicted, cm^2", "gradient true / predicted, mmHg",
             "stenosis true / predicted", "rank true / predicted", "failed"},
            rows);
  // What the study cost, from its records (a run resumed over several sessions or machines
  // reports the whole, where its wall time below is only its own).
  double observe_s = 0, calibrate_s = 0, predict_s = 0, truth_s = 0;
  for (const json& m : r.scanned) observe_s += m.value("observe_s", 0.0);
  for (const auto& p : r.patients) {
    calibrate_s += p.calibrate_s;
    predict_s += p.predict_s;
    for (const auto& op : p.options) truth_s += op.truth_s;
  }
  rep.paragraph("Compute, summed over the records (one core each; 0 for what a cache held): " +
                number((observe_s + calibrate_s + predict_s + truth_s) / 3600.0, 1) +
                " h: observations " + number(observe_s / 3600.0, 2) + " h, calibrations " +
                number(calibrate_s / 3600.0, 2) + " h, predictions with their intervals " +
                number(predict_s / 3600.0, 2) + " h, truths " + number(truth_s / 3600.0, 2) +
                " h.");
  {
    Plot fig;
    fig.title = "Predicted against true EROA (no clip and every option)";
    fig.x_label = "true EROA, mm^2 (fine model, hidden parameters)";
    fig.y_label = "predicted EROA, mm^2";
    PlotSeries cal{"calibrated (95 % interval)", {}, {}, false, true, {}},
        def{"default parameters", {}, {}, false, true, {}},
        id_line{"y = x", {}, {}, true, false, {}};
    double hi = 0;
    auto add = [&](double truth, double pv, double sd, double d) {
      if (!std::isfinite(truth)) return;
      if (std::isfinite(pv)) {
        cal.x.push_back(truth);
        cal.y.push_back(pv);
        cal.y_error.push_back(std::isfinite(sd) ? inverse::kZ95 * sd : 0.0);
        hi = std::max(hi, std::max(truth, pv));
      }
      if (std::isfinite(d)) {
        def.x.push_back(truth);
        def.y.push_back(d);
        hi = std::max(hi, std::max(truth, d));
      }
    };
    for (const auto& p : r.patients) {
      add(p.eroa_no_clip_true_mm2, p.eroa_no_clip_predicted_mm2, p.eroa_no_clip_predicted_sd_mm2,
          p.eroa_no_clip_default_mm2);
      for (const auto& op : p.options)
        add(op.eroa_true_mm2, op.eroa_predicted_mm2, op.eroa_predicted_sd_mm2, op.eroa_default_mm2);
    }
    id_line.x = {0.0, hi};
    id_line.y = {0.0, hi};
    if (!cal.x.empty() || !def.x.empty()) {
      for (PlotSeries* ps : {&cal, &def})
        if (!ps->x.empty()) fig.series.push_back(*ps);
      fig.series.push_back(id_line);
      fig.write_png(f.path("eroa_predicted_vs_true.png"));
      rep.figure("eroa_predicted_vs_true.png",
                 "Each point one patient without a clip or with one option; on the line the "
                 "prediction is the truth.");
    }
  }
  rep.how_made(o.command, r.workers, r.wall_s);
  rep.write(f.dir());
}

}  // namespace

}  // namespace mvtwin::studies
