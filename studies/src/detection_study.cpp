#include "mvtwin/studies/detection_study.h"

#include <opencv2/core.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/cache_key.h"
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

namespace {

/// Test patient i is member 500 + i of the cohort: disjoint from the training members 0..499.
constexpr int kTestOffset = 500;

std::uint64_t test_seed(const DetectionStudyOptions& o, int i) {
  return virtual_cohort_seed(o.seed, kTestOffset + i);
}

std::string noise_text(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

json render_json(const detection::TeeRenderOptions& r) {
  return {{"voxel_mm", r.voxel_mm},
          {"box_mm", r.box_mm},
          {"sector_deg", r.sector_deg},
          {"probe_depth_mm", r.probe_depth_mm},
          {"probe_jitter_deg", r.probe_jitter_deg},
          {"axial_psf_mm", r.axial_psf_mm},
          {"lateral_psf_mm", r.lateral_psf_mm},
          {"attenuation_db_per_mm", r.attenuation_db_per_mm},
          {"dynamic_range_db", r.dynamic_range_db},
          {"speckle", r.speckle},
          {"dropout_fraction", r.dropout_fraction},
          {"blood", r.blood}};
}

json detector_json(const detection::DetectorOptions& d) {
  return {{"scales", d.scales},
          {"trees", d.trees},
          {"max_depth", d.max_depth},
          {"samples_per_volume", d.samples_per_volume},
          {"position_step_mm", d.position_step_mm},
          {"landmark_search_mm", d.landmark_search_mm},
          {"track_search_mm", d.track_search_mm},
          {"normal_search_mm", d.normal_search_mm},
          {"surface_iterations", d.surface_iterations},
          {"seed", d.seed}};
}

/// The ids a model file was trained on (its provenance, as mvtwin train-detector and this
/// study write it: "id,id,... (synthetic)").
std::vector<std::string> training_ids(const fs::path& model) {
  std::vector<std::string> ids;
  for (const auto& [name, value] : detection::ValveDetector::provenance(model))
    if (name == "training_patients") {
      std::stringstream ss(value.substr(0, value.find(' ')));
      for (std::string id; std::getline(ss, id, ',');) ids.push_back(id);
    }
  return ids;
}

void write_outputs(const DetectionStudyOptions& o, const DetectionStudyResult& r,
                   const StudyFolder& folder);

}  // namespace

// ---- options -----------------------------------------------------------------------------------

detection::TeeRenderOptions DetectionStudyOptions::default_render() {
  detection::TeeRenderOptions r;
  r.probe_jitter_deg = 10;
  return r;
}

bool DetectionStudyOptions::is_valid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (out.empty()) return fail("detection study: no output folder (--out)");
  if (model_file.empty() && (train < 3 || train > kTestOffset))
    return fail("detection study: training patients must be 3 to " + std::to_string(kTestOffset) +
                ", not " + std::to_string(train));
  if (test < 1 || test > 100000)
    return fail("detection study: test patients must be 1 to 100000, not " + std::to_string(test));
  if (jobs < 1 || jobs > 256) return fail("detection study: jobs must be 1 to 256");
  if (noise_levels.empty()) return fail("detection study: no noise level");
  std::set<double> seen;
  for (double l : noise_levels) {
    if (!(l >= 0 && l <= 10))
      return fail("detection study: noise levels must be 0 to 10, not " + noise_text(l));
    if (!seen.insert(l).second)
      return fail("detection study: noise level " + noise_text(l) + " given twice");
  }
  for (double l : train_noise)
    if (!(l >= 0 && l <= 10))
      return fail("detection study: training noise levels must be 0 to 10, not " + noise_text(l));
  detection::TeeRenderOptions check = render;
  check.noise = noise_levels.front();
  if (const std::string e = check.invalid(); !e.empty()) return fail("detection study: " + e);
  if (const std::string e = detector.invalid(); !e.empty()) return fail("detection study: " + e);
  if (!model_file.empty() && !fs::is_regular_file(model_file))
    return fail("detection study: no model file " + model_file.string());
  try {
    const VirtualTeeTruth t(truth_sets);
    std::string e;
    if (!t.closure.simulation.is_valid(&e)) return fail("detection study: truth model: " + e);
  } catch (const std::exception& e) {
    return fail(std::string("detection study: truth model: ") + e.what());
  }
  return true;
}

DetectionStudyOptions DetectionStudyOptions::quick() {
  DetectionStudyOptions o;
  o.train = 3;
  o.test = 1;
  o.noise_levels = {0.004, 0.1};
  o.train_noise = {0.004};
  o.render.voxel_mm = 2.5;
  // A wider point-spread function: the renderer samples beams at the PSF's resolution, so this
  // makes the test's images about 6x cheaper.
  o.render.axial_psf_mm = 0.5;
  o.render.lateral_psf_mm = 2.2;
  o.detector.trees = 8;
  o.detector.samples_per_volume = 300;
  o.truth_sets = {"ures=16", "vres=8"};
  return o;
}

json DetectionStudyOptions::config() const {
  const VirtualTeeTruth t(truth_sets);
  json c{{"seed", seed},
         {"virtual_patient_edition", kVirtualPatientEdition},
         {"truth_model", detail::describe(t.closure.simulation)},
         {"render", render_json(render)}};
  if (model_file.empty()) {
    c.update(
        {{"train", train}, {"train_noise", train_noise}, {"detector", detector_json(detector)}});
  } else {
    c["model_file"] = fs::absolute(model_file).lexically_normal().string();
  }
  return c;
}

// ---- a detection's record ----------------------------------------------------------------------

json DetectionRun::to_json() const {
  json j{{"patient", patient},
         {"patient_seed", patient_seed},
         {"id", id},
         {"pathology", pathology},
         {"noise", noise},
         {"ok", ok},
         {"frames", frames.is_null() ? json::array() : frames}};
  if (!reason.empty()) j["reason"] = reason;
  return j;
}

DetectionRun DetectionRun::from_json(const json& j) {
  DetectionRun r;
  r.patient = j.value("patient", 0);
  r.patient_seed = j.value("patient_seed", std::uint64_t{0});
  r.id = j.value("id", "");
  r.pathology = j.value("pathology", "");
  r.noise = j.value("noise", 0.0);
  r.ok = j.value("ok", false);
  r.reason = j.value("reason", "");
  r.frames = j.value("frames", json::array());
  return r;
}

// ---- the study ---------------------------------------------------------------------------------

DetectionStudyResult run_detection_study(const DetectionStudyOptions& o, WorkPool& pool) {
  std::string err;
  if (!o.is_valid(&err)) throw Error(err);
  const auto t0 = std::chrono::steady_clock::now();
  const VirtualTeeTruth truth(o.truth_sets);
  std::vector<std::string> test_ids;
  for (int i = 0; i < o.test; ++i) test_ids.push_back("virtual-" + std::to_string(test_seed(o, i)));
  const fs::path cache = o.cache.empty() ? o.out / "cache" : o.cache;

  // The detector: a given model (none of the test patients among its training ones: checked
  // before anything is written), or one trained here, named by everything that makes it.
  fs::path model_path;
  if (!o.model_file.empty()) {
    model_path = o.model_file;
    for (const std::string& id : training_ids(model_path))
      if (std::find(test_ids.begin(), test_ids.end(), id) != test_ids.end())
        throw Error("detection study: " + model_path.string() + " was trained on test patient " +
                    id + " (choose another --seed)");
  } else {
    detection::TeeRenderOptions train_render = o.render;
    train_render.noise = o.noise_levels.front();
    const std::string key = cache_key(
        truth.key + " seed=" + std::to_string(o.seed) + " train=" + std::to_string(o.train) +
        " render=" + render_json(train_render).dump() + " " + detector_json(o.detector).dump() +
        " train_noise=" + json(o.train_noise).dump());
    model_path = cache / ("detector_" + key + ".yml.gz");
  }
  const std::unique_ptr<StudyFolder> folder =
      open_study_folder(pool, o.out, "detection", o.config());
  if (pool.is_root()) create_output_directory(cache);
  pool.barrier();
  const bool must_train = o.model_file.empty() && !fs::exists(model_path);

  std::mutex progress_mutex;
  auto report = [&](const std::string& stage, int done, int total, const std::string& msg) {
    if (!o.progress) return;
    std::lock_guard<std::mutex> lock(progress_mutex);
    o.progress({stage, done, total, msg});
  };

  // Stage 1: the truths (simulated closing frames, cached), one patient per work item.
  std::atomic<int> done{0};
  {
    const int n_train = must_train ? o.train : 0;
    const int n = n_train + o.test;
    pool.map(n, o.jobs, [&](int k) -> std::string {
      const bool training = k < n_train;
      const int i = training ? k : k - n_train;
      const std::uint64_t ps = training ? virtual_cohort_seed(o.seed, i) : test_seed(o, i);
      std::string msg = (training ? "training " : "test ") + std::string("virtual-") +
                        std::to_string(ps) + " [SYNTHETIC]";
      try {
        virtual_tee_patient(ps, i, truth, cache);
        msg += ": ready";
      } catch (const std::exception& e) {
        msg += std::string(": no truth (") + e.what() + ")";
      }
      report("truth", ++done, n, msg);
      return {};
    });
  }

  // Stage 2: training, one work item (whichever process takes it); its figures are a record.
  DetectionStudyResult result;
  {
    const auto out = pool.map(1, 1, [&](int) -> std::string {
      if (auto rec = folder->record("detector");
          rec && fs::exists(model_path) && rec->value("file", "") == model_path.string())
        return rec->dump();
      json rec{{"file", model_path.string()}};
      try {
        if (must_train) {
          std::vector<std::uint64_t> seeds;
          for (int i = 0; i < o.train; ++i) seeds.push_back(virtual_cohort_seed(o.seed, i));
          detection::TeeRenderOptions train_render = o.render;
          train_render.noise = o.noise_levels.front();
          VirtualTrainingResult tr = train_on_virtual_cohort(
              seeds, truth, train_render, o.train_noise, o.detector, o.jobs, cache,
              [&](const std::string& line) { report("train", 0, 1, line); });
          std::string ids;
          for (const auto& id : tr.patients) ids += (ids.empty() ? "" : ",") + id;
          tr.detector.save(model_path, {{"mvtwin_version", std::string(kVersion)},
                                        {"command", o.command},
                                        {"created_utc", utc_now_iso8601()},
                                        {"training_patients", ids + " (synthetic)"},
                                        {"training_volumes", std::to_string(tr.volumes)},
                                        {"train_s", std::to_string(tr.train_s)}});
          rec.update({{"training_patients", tr.patients},
                      {"training_volumes", tr.volumes},
                      {"train_s", tr.train_s},
                      {"prepare_s", tr.prepare_s}});
        } else {
          rec["training_patients"] = training_ids(model_path);
          for (const auto& [name, value] : detection::ValveDetector::provenance(model_path)) {
            if (name == "training_volumes") rec["training_volumes"] = std::atoi(value.c_str());
            if (name == "train_s") rec["train_s"] = std::atof(value.c_str());
          }
        }
        rec["ok"] = true;
        folder->save_record("detector", rec);
        report("train", 1, 1, "detector: " + model_path.string());
      } catch (const std::exception& e) {
        rec.update({{"ok", false}, {"reason", e.what()}});
      }
      return rec.dump();
    });
    const json rec = json::parse(out.at(0));
    if (!rec.value("ok", false))
      throw Error("detection study: no detector: " + rec.value("reason", std::string("?")));
    result.detector_file = model_path;
    result.training_patients = rec.value("training_patients", std::vector<std::string>{});
    result.training_volumes = rec.value("training_volumes", 0);
    result.train_s = rec.value("train_s", 0.0);
  }
  const detection::ValveDetector detector = detection::ValveDetector::load(model_path);

  // Stage 3: every test patient at every noise level, one detection per work item; each
  // detection on one core (its s per volume is one core's).
  const int threads = cv::getNumThreads();
  cv::setNumThreads(1);
  const int n_levels = static_cast<int>(o.noise_levels.size());
  const int n_runs = n_levels * o.test;
  done = 0;
  const auto out = pool.map(n_runs, o.jobs, [&](int k) -> std::string {
    const double noise = o.noise_levels[static_cast<std::size_t>(k / o.test)];
    const int i = k % o.test;
    char name[64];
    std::snprintf(name, sizeof name, "detect_%04d_noise_%s", i, noise_text(noise).c_str());
    if (auto rec = folder->record(name)) {
      report("detect", ++done, n_runs, std::string(name) + ": done before (resumed)");
      return rec->dump();
    }
    DetectionRun run;
    run.patient = i;
    run.patient_seed = test_seed(o, i);
    run.id = "virtual-" + std::to_string(run.patient_seed);
    run.noise = noise;
    try {
      const Patient p = virtual_tee_patient(run.patient_seed, i, truth, cache);
      run.id = p.id;
      run.pathology = p.truth ? std::string(pathology_name(p.truth->pathology)) : "";
      detection::TeeRenderOptions ro = o.render;
      ro.noise = noise;
      const std::vector<ImageVolume> images = render_virtual_tee(p, ro);
      std::vector<detection::DetectionInfo> info;
      const std::vector<ValveFrame> det = detector.detect_sequence(images, &info);
      run.frames = detection_errors(p, det, info);
      run.ok = true;
    } catch (const std::exception& e) {
      run.reason = e.what();
    }
    const json j = run.to_json();
    folder->save_record(name, j);
    std::string msg = run.id + " [SYNTHETIC] at noise " + noise_text(noise) + ": ";
    if (run.ok) {
      const json s = summarize_detections({&j});
      msg += "surface " + number(s["error_mean_mm"].get<double>()) + " mm, papillary " +
             number(s["papillary_error_mm"].get<double>()) + " mm, " +
             number(s["s_per_volume"].get<double>()) + " s/volume";
    } else {
      msg += "failed (" + run.reason + ")";
    }
    report("detect", ++done, n_runs, msg);
    return j.dump();
  });
  cv::setNumThreads(threads);

  std::vector<json> rows;
  for (const auto& s : out) {
    rows.push_back(json::parse(s));
    result.runs.push_back(DetectionRun::from_json(rows.back()));
  }
  for (double l : o.noise_levels) {
    std::vector<const json*> at;
    for (const auto& r : rows)
      if (r.value("ok", false) && r.value("noise", -1.0) == l) at.push_back(&r);
    if (at.empty()) continue;
    json s = summarize_detections(at);
    s["noise"] = l;
    if (l == o.noise_levels.front()) result.headline = s;
    result.curve.push_back(s);
  }
  result.workers = pool.describe();
  result.wall_s = detail::seconds_since(t0);
  if (pool.is_root()) write_outputs(o, result, *folder);
  pool.barrier();
  return result;
}

// ---- outputs -----------------------------------------------------------------------------------

namespace {

double field(const json& j, const char* key) { return detail::number_at(j, key); }

void write_outputs(const DetectionStudyOptions& o, const DetectionStudyResult& r,
                   const StudyFolder& folder) {
  json prov = detail::provenance(o.command, r.workers, r.wall_s);
  prov["seed"] = o.seed;
  json runs = json::array();
  for (const auto& run : r.runs) runs.push_back(run.to_json());
  std::vector<std::string> test_ids;
  for (int i = 0; i < o.test; ++i) test_ids.push_back("virtual-" + std::to_string(test_seed(o, i)));
  const VirtualTeeTruth truth(o.truth_sets);
  write_json(folder.path("study.json"), {{"format", "mvtwin-detection-study"},
                                         {"study", "detection"},
                                         {"synthetic", true},
                                         {"config", o.config()},
                                         {"provenance", prov},
                                         {"noise_levels", o.noise_levels},
                                         {"detector",
                                          {{"file", r.detector_file.string()},
                                           {"training_patients", r.training_patients},
                                           {"training_volumes", r.training_volumes},
                                           {"train_s", r.train_s}}},
                                         {"test_patients", test_ids},
                                         {"headline", r.headline},
                                         {"curve", r.curve},
                                         {"runs", runs}});

  // One row per detected frame (h5py, pandas).
  TableFile t;
  t.format = "mvtwin-detection-study";
  t.attributes = {{"mvtwin_version", kVersion},
                  {"command", o.command},
                  {"created_utc", prov["created_utc"].get<std::string>()},
                  {"seed", std::to_string(o.seed)},
                  {"synthetic", "1"},
                  {"config", o.config().dump()}};
  TableColumn id{"id", "", {}, {}}, pathology{"pathology", "", {}, {}}, phase{"phase", "", {}, {}},
      noise{"noise", "", {}, {}}, frame{"frame", "", {}, {}}, time{"time_s", "s", {}, {}},
      surface{"surface_error_mm", "mm", {}, {}}, seconds{"seconds", "s", {}, {}};
  std::vector<TableColumn> landmarks;
  for (int l = 0; l < kNumLandmarks; ++l)
    landmarks.push_back(
        {std::string(kLandmarkNames[static_cast<std::size_t>(l)]) + "_error_mm", "mm", {}, {}});
  for (const auto& run : r.runs) {
    if (!run.ok) continue;
    for (const auto& f : run.frames) {
      id.strings.push_back(run.id);
      pathology.strings.push_back(run.pathology.empty() ? "-" : run.pathology);
      phase.strings.push_back(f.value("phase", "-"));
      noise.numbers.push_back(run.noise);
      frame.numbers.push_back(f.value("frame", 0));
      time.numbers.push_back(field(f, "time_s"));
      surface.numbers.push_back(field(f, "surface_error_mm"));
      seconds.numbers.push_back(field(f, "seconds"));
      for (int l = 0; l < kNumLandmarks; ++l) {
        const std::string n(kLandmarkNames[static_cast<std::size_t>(l)]);
        const json& lm = f["landmark_error_mm"];
        landmarks[static_cast<std::size_t>(l)].numbers.push_back(
            lm.contains(n) ? lm[n].get<double>() : kNaN);
      }
    }
  }
  t.columns = {id, pathology, phase, noise, frame, time, surface, seconds};
  for (auto& c : landmarks) t.columns.push_back(std::move(c));
  if (!id.strings.empty()) write_table_file(folder.path("study.h5"), t);

  constexpr double kPaperError = 2.75, kPaperSd = 0.86, kPaperSeconds = 4.8;
  Report rep("Detection study: the valve from synthetic 3D+t TEE");
  rep.paragraph("Compared with " + std::string(kPaperCitation) +
                " (its Sec. 3.1: 2.75 ± 0.86 mm point-to-mesh error against manual delineation, "
                "three-fold cross-validation on 200 3D+t TEE sequences of 120 patients; 4.8 s "
                "per volume on a 2.66 GHz Core2 quad). The paper's detector was trained and "
                "tested on real TEE; these figures are on **SYNTHETIC** images of virtual "
                "patients and say how the pipeline behaves, not how it does on patients.");
  rep.paragraph(
      "Test cohort: " + std::to_string(o.test) + " virtual patient" + (o.test > 1 ? "s" : "") +
      " (member" + (o.test > 1 ? "s " : " ") + std::to_string(kTestOffset) +
      (o.test > 1 ? "-" + std::to_string(kTestOffset + o.test - 1) : "") + " of cohort seed " +
      std::to_string(o.seed) +
      ", pathologies in turn). Their closing frames were simulated without noise (the truth) by "
      "the model `" +
      std::to_string(truth.closure.simulation.model.ures) + " x " +
      std::to_string(truth.closure.simulation.model.vres) + "`, and every frame rendered as TEE: " +
      number(o.render.voxel_mm, 2) + " mm voxels, PSF " + number(o.render.axial_psf_mm, 2) +
      " mm axial and " + number(o.render.lateral_psf_mm, 2) + " mm lateral, " +
      number(o.render.sector_deg, 0) + " degree sector, probe pose varied by up to " +
      number(o.render.probe_jitter_deg, 0) + " degrees, speckle " + number(o.render.speckle, 2) +
      ", " + number(100 * o.render.dropout_fraction, 0) + " % of beams with a drop-out. " +
      (o.model_file.empty()
           ? "Detector: trained by this study on " + std::to_string(r.training_patients.size()) +
                 " other virtual patients (" + std::to_string(r.training_volumes) +
                 " volumes, their renders' noise cycling through " + json(o.train_noise).dump() +
                 ")."
           : "Detector: the given model `" + o.model_file.string() + "` (" +
                 std::to_string(r.training_patients.size()) +
                 " training patients, none of the test ones)."));
  rep.paragraph(
      "Error: symmetric point-to-mesh distance between the detected and the true left-atrial "
      "leaflet surface, over every frame with a known surface; landmarks and papillary tips: "
      "distance to the truth where both are observed. Time: detection of one volume on one "
      "core.");
  rep.heading("mvtwin next to the paper");
  const json& h = r.headline;
  std::vector<std::vector<std::string>> rows;
  if (!h.is_null()) {
    rows.push_back({"surface error, mm (noise " + noise_text(o.noise_levels.front()) + ")",
                    mean_sd(field(h, "error_mean_mm"), field(h, "error_sd_mm")) + " (" +
                        std::to_string(h["frames"].get<int>()) + " frames of " +
                        std::to_string(h["patients"].get<int>()) + " patient" +
                        (h["patients"].get<int>() > 1 ? "s)" : ")"),
                    mean_sd(kPaperError, kPaperSd) + " (200 sequences, 120 patients)"});
    rows.push_back({"worst frame, mm", number(field(h, "error_max_frame_mm")), "-"});
    if (h["patients"].get<int>() > 1)
      rows.push_back(
          {"SD of the patients' means, mm", number(field(h, "error_patient_mean_sd_mm")), "-"});
    rows.push_back({"papillary tips, mm", number(field(h, "papillary_error_mm")), "-"});
    rows.push_back({"time per volume, s (one core)", number(field(h, "s_per_volume")),
                    number(kPaperSeconds, 1) + " (2012 hardware)"});
  }
  rep.table({"", "mvtwin (SYNTHETIC)", "paper (real TEE)"}, rows);

  rep.heading("Error against image noise");
  rows.clear();
  for (const auto& c : r.curve) {
    auto ph = [&](const char* p) {
      return c["by_phase"].contains(p) ? number(field(c["by_phase"][p], "error_mean_mm")) : "-";
    };
    rows.push_back({noise_text(c["noise"].get<double>()), std::to_string(c["patients"].get<int>()),
                    std::to_string(c["frames"].get<int>()),
                    mean_sd(field(c, "error_mean_mm"), field(c, "error_sd_mm")), ph("open"),
                    ph("closing"), ph("closed"), number(field(c, "papillary_error_mm")),
                    number(field(c, "s_per_volume"))});
  }
  rep.table({"noise SD", "patients", "frames", "surface, mm", "open", "closing", "closed",
             "papillary, mm", "s / volume"},
            rows);
  if (!r.curve.empty()) {
    // Bars by level (sorted), the paper's mean as a line.
    std::vector<const json*> sorted;
    for (const auto& c : r.curve) sorted.push_back(&c);
    std::sort(sorted.begin(), sorted.end(), [](const json* a, const json* b) {
      return (*a)["noise"].get<double>() < (*b)["noise"].get<double>();
    });
    Plot fig;
    fig.title = "Detection error against image noise (SYNTHETIC)";
    fig.x_label = "electronic noise SD of the renders";
    fig.y_label = "error, mm";
    PlotSeries surf{"leaflet surface (SD over frames)", {}, {}, false, true, {}},
        pap{"papillary tips", {}, {}, false, true, {}};
    for (const json* c : sorted) {
      fig.categories.push_back(noise_text((*c)["noise"].get<double>()));
      surf.y.push_back(field(*c, "error_mean_mm"));
      surf.y_error.push_back(field(*c, "error_sd_mm"));
      pap.y.push_back(field(*c, "papillary_error_mm"));
    }
    fig.series = {surf, pap};
    fig.h_lines = {{kPaperError, "paper, real TEE: 2.75 mm"}};
    fig.write_png(folder.path("noise_curve.png"));
    rep.figure("noise_curve.png",
               "Mean error of the detected leaflet surface and papillary tips at each noise level "
               "(bars: SD over frames); the dashed line is the paper's surface error on real TEE.");
  }
  // The error over the cycle at the headline level, one line per test patient.
  {
    Plot fig;
    fig.title = "Leaflet error over the cycle, noise " + noise_text(o.noise_levels.front());
    fig.x_label = "time, ms";
    fig.y_label = "surface error, mm";
    for (const auto& run : r.runs) {
      if (!run.ok || run.noise != o.noise_levels.front()) continue;
      // Short names (the ids are 19 digits): the cohort member and pathology.
      PlotSeries s{
          "member " + std::to_string(kTestOffset + run.patient) + " (" + run.pathology + ")",
          {},
          {},
          true,
          true,
          {}};
      for (const auto& f : run.frames)
        if (f.contains("surface_error_mm")) {
          s.x.push_back(1000 * field(f, "time_s"));
          s.y.push_back(field(f, "surface_error_mm"));
        }
      if (!s.x.empty()) fig.series.push_back(s);
    }
    if (!fig.series.empty()) {
      fig.h_lines = {{kPaperError, "paper: 2.75 mm"}};
      fig.write_png(folder.path("error_over_cycle.png"));
      rep.figure("error_over_cycle.png",
                 "Surface error of every test patient frame by frame (open, closing, closed).");
    }
  }
  if (!h.is_null() && h.contains("landmark_error_mm") && !h["landmark_error_mm"].empty()) {
    rep.heading("Landmarks");
    rows.clear();
    Plot fig;
    fig.title = "Landmark error, noise " + noise_text(o.noise_levels.front());
    fig.x_label = "landmark";
    fig.y_label = "mean distance to the truth, mm";
    PlotSeries s{"mvtwin (SYNTHETIC)", {}, {}, false, true, {}};
    for (const auto& [name, e] : h["landmark_error_mm"].items()) {
      rows.push_back({name, number(e.get<double>())});
      std::string label = name;
      std::replace(label.begin(), label.end(), '_', ' ');
      fig.categories.push_back(label);
      s.y.push_back(e.get<double>());
    }
    rep.table({"landmark", "mean error, mm"}, rows);
    fig.series = {s};
    fig.width = 1100;
    fig.write_png(folder.path("landmarks.png"));
    rep.figure("landmarks.png", "Mean distance of each detected landmark to the truth.");
  }
  bool failures = false;
  for (const auto& run : r.runs)
    if (!run.ok) {
      if (!failures) rep.heading("Failures");
      failures = true;
      rep.paragraph("`" + run.id + "` at noise " + noise_text(run.noise) + ": " + run.reason);
    }
  rep.how_made(o.command, r.workers, r.wall_s);
  rep.write(folder.dir());
}

}  // namespace

}  // namespace mvtwin::studies
