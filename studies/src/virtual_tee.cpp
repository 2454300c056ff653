#include "mvtwin/studies/virtual_tee.h"

#include <opencv2/core.hpp>

#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <sstream>

#include "mvtwin/core/cache_key.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/point_to_mesh_distance.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/studies/study_folder.h"
#include "mvtwin/studies/work_pool.h"
#include "study_util.h"

namespace mvtwin::studies {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

const char* phase_of(const ValveSequence& s, int f) {
  if (s.end_diastole >= 0 && f <= s.end_diastole) return "open";
  if (s.first_closed >= 0 && f >= s.first_closed) return "closed";
  return "closing";
}

double mean_of(const std::vector<double>& v) { return detail::stats(v).mean; }

std::string number_text(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

json detection_errors(const Patient& truth, const std::vector<ValveFrame>& detected,
                      const std::vector<detection::DetectionInfo>& info) {
  json frames = json::array();
  for (std::size_t f = 0; f < detected.size(); ++f) {
    const ValveFrame& t = truth.sequence.frames[f];
    json row{{"frame", f},
             {"time_s", t.time_s},
             {"phase", phase_of(truth.sequence, static_cast<int>(f))},
             {"seconds", info[f].seconds}};
    if (t.la_surface && detected[f].la_surface) {
      const SymmetricDistance d = symmetric_surface_distance(detected[f].la_surface->triangulate(),
                                                             t.la_surface->triangulate());
      row["surface_error_mm"] = d.symmetric.mean;
      row["truth_to_detected_mm"] = d.b_to_a.mean;
    }
    json lm = json::object();
    for (int l = 0; l < kNumLandmarks; ++l) {
      const auto i = static_cast<std::size_t>(l);
      if (t.landmark_observed[i] && detected[f].landmark_observed[i])
        lm[std::string(kLandmarkNames[i])] = (detected[f].landmarks[i] - t.landmarks[i]).norm();
    }
    row["landmark_error_mm"] = lm;
    frames.push_back(row);
  }
  return frames;
}

json summarize_detections(const std::vector<const json*>& runs) {
  std::vector<double> all, seconds, papillary, patient_means;
  std::map<std::string, std::vector<double>> by_phase, by_landmark;
  for (const json* r : runs) {
    std::vector<double> mine;
    for (const json& f : (*r)["frames"]) {
      seconds.push_back(f["seconds"].get<double>());
      if (f.contains("surface_error_mm")) {
        const double e = f["surface_error_mm"].get<double>();
        all.push_back(e);
        mine.push_back(e);
        by_phase[f["phase"].get<std::string>()].push_back(e);
      }
      for (const auto& [name, e] : f["landmark_error_mm"].items()) {
        by_landmark[name].push_back(e.get<double>());
        if (name.find("papillary") != std::string::npos) papillary.push_back(e.get<double>());
      }
    }
    if (!mine.empty()) patient_means.push_back(mean_of(mine));
  }
  json lm = json::object();
  for (const auto& [name, v] : by_landmark) lm[name] = mean_of(v);
  json phase = json::object();
  for (const auto& [name, v] : by_phase)
    phase[name] = {{"error_mean_mm", mean_of(v)}, {"frames", v.size()}};
  const detail::Stats st = detail::stats(all);
  const double m = st.mean, sd = st.sd;
  double worst = 0;
  for (double e : all) worst = std::max(worst, e);
  return {{"patients", runs.size()},
          {"frames", all.size()},
          {"error_mean_mm", m},
          {"error_sd_mm", sd},
          {"error_max_frame_mm", worst},
          {"error_patient_mean_sd_mm", detail::stats(patient_means).sd},
          {"by_phase", phase},
          {"landmark_error_mm", lm},
          {"papillary_error_mm", mean_of(papillary)},
          {"s_per_volume", mean_of(seconds)}};
}

VirtualTeeTruth::VirtualTeeTruth(const std::vector<std::string>& sets) {
  closure.simulation = forward::ClosureOptions{};
  closure.noise_mm = 0.0;
  for (const auto& a : sets)
    forward::apply_option(a, &closure.simulation,
                          "the truths are simulated with the virtual patients' hidden parameters");
  std::string description = "truth patients=" + std::to_string(kVirtualPatientEdition);
  for (const auto& [name, value] : forward::describe_result_options(closure.simulation))
    description += " " + name + "=" + value;
  key = cache_key(description);
}

Patient virtual_tee_patient(std::uint64_t seed, int i, const VirtualTeeTruth& truth,
                            const fs::path& cache) {
  const fs::path cached = cache.empty()
                              ? fs::path()
                              : cache / ("truth_" + std::to_string(seed) + "_" + truth.key + ".h5");
  if (!cached.empty()) {
    std::lock_guard<std::mutex> lock(hdf5_mutex());
    if (fs::exists(cached)) return read_patient(cached, false);
  }
  VirtualPatientOptions po;
  po.pathology = static_cast<Pathology>(i % kNumPathologies);
  Patient p = make_virtual_patient(seed, po);
  forward::simulate_observed_closure(&p, truth.closure);
  if (!cached.empty()) {
    std::lock_guard<std::mutex> lock(hdf5_mutex());
    fs::create_directories(cache);
    write_patient(cached, p);
  }
  return p;
}

std::vector<ImageVolume> render_virtual_tee(const Patient& p, detection::TeeRenderOptions render) {
  render.seed = p.provenance.seed;
  return detection::render_tee(p.sequence, render);
}

VirtualTrainingResult train_on_virtual_cohort(const std::vector<std::uint64_t>& seeds,
                                              const VirtualTeeTruth& truth,
                                              const detection::TeeRenderOptions& render,
                                              const std::vector<double>& noise,
                                              const detection::DetectorOptions& options, int jobs,
                                              const fs::path& cache,
                                              const std::function<void(const std::string&)>& log) {
  std::mutex log_mutex;
  auto say = [&](const std::string& line) {
    std::lock_guard<std::mutex> lock(log_mutex);
    if (log) log(line);
  };
  std::vector<Patient> train(seeds.size());
  std::vector<std::vector<ImageVolume>> images(seeds.size());
  std::vector<bool> ok(seeds.size(), false);
  const auto t0 = std::chrono::steady_clock::now();
  const int n = static_cast<int>(seeds.size());
  make_local_pool()->map(n, jobs, [&](int i) -> std::string {
    const auto k = static_cast<std::size_t>(i);
    const std::string which = "training patient " + std::to_string(i + 1) + "/" + std::to_string(n);
    try {
      train[k] = virtual_tee_patient(seeds[k], i, truth, cache);
      detection::TeeRenderOptions o = render;
      if (!noise.empty()) o.noise = noise[k % noise.size()];
      images[k] = render_virtual_tee(train[k], o);
      ok[k] = true;
      std::ostringstream line;
      line << which << " (" << train[k].id << " [SYNTHETIC], "
           << pathology_name(train[k].truth->pathology) << "): " << images[k].size()
           << " volumes rendered (noise " << o.noise << ")";
      say(line.str());
    } catch (const Error& e) {
      say(which + ": skipped (" + e.what() + ")");
    }
    return {};
  });
  VirtualTrainingResult r;
  std::vector<detection::TrainingVolume> data;
  for (std::size_t k = 0; k < seeds.size(); ++k) {
    if (!ok[k]) continue;
    r.patients.push_back(train[k].id);
    for (std::size_t f = 0; f < images[k].size(); ++f)
      if (train[k].sequence.frames[f].la_surface)
        data.push_back({&images[k][f], &train[k].sequence.frames[f]});
  }
  r.volumes = static_cast<int>(data.size());
  r.prepare_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  say("training on " + std::to_string(data.size()) + " volumes of " +
      std::to_string(r.patients.size()) + " patients (" + number_text(r.prepare_s) +
      " s to simulate and render)");
  const int threads = cv::getNumThreads();
  cv::setNumThreads(jobs);
  const auto t1 = std::chrono::steady_clock::now();
  r.detector =
      detection::ValveDetector::train(data, options, [&](const std::string& s) { say("  " + s); });
  r.train_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  cv::setNumThreads(threads);
  say("trained in " + number_text(r.train_s) + " s");
  return r;
}

}  // namespace mvtwin::studies
