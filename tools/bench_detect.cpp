// mvtwin bench detect: valve detection from synthetic 3D+t TEE on a held-out virtual cohort,
// with a curve of error against noise (figures, not tests).
#include <opencv2/core.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "jobs.h"
#include "output_files.h"
#include "virtual_tee.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/version.h"
#include "mvtwin/detection/tee_renderer.h"
#include "mvtwin/detection/valve_detector.h"
#include "mvtwin/forward/closure_settings.h"

namespace mvtwin::tools {
namespace fs = std::filesystem;
using nlohmann::json;

void register_bench_detect(CLI::App& bench, Context& ctx) {
  auto* cmd = bench.add_subcommand("detect", "Valve detection from synthetic TEE on a held-out virtual cohort");
  cmd->footer(
      "Example:\n  mvtwin bench detect --json detect.json --cache det/\n"
      "Two disjoint virtual cohorts (pathologies in turn): their closing frames are simulated\n"
      "(--truth-set; the calibration model by default, without noise: the truth to detect), every\n"
      "frame is rendered as synthetic TEE (--voxel, --probe-jitter, --speckle, --dropout), a\n"
      "detector is trained on the first cohort and run on the second at each --noise-levels\n"
      "(electronic noise SD; the first level is the headline; the training renders cycle through\n"
      "--train-noise). Errors are against the virtual\n"
      "truth over every frame with a known surface; s_per_volume is detection on one core\n"
      "(--jobs patients at once). --cache keeps the truths and the model; the JSON resumes.");
  auto json_path = std::make_shared<std::string>();
  auto cache = std::make_shared<std::string>();
  auto n_train = std::make_shared<int>(12);
  auto n_test = std::make_shared<int>(6);
  auto seed = std::make_shared<unsigned>(3030);
  auto jobs = std::make_shared<int>(2);
  auto truth_sets = std::make_shared<std::vector<std::string>>();
  auto levels = std::make_shared<std::vector<double>>(std::vector<double>{0.004, 0.0, 0.016, 0.063, 0.25});
  auto ro = std::make_shared<detection::TeeRenderOptions>();
  ro->probe_jitter_deg = 10;
  auto dopt = std::make_shared<detection::DetectorOptions>();
  cmd->add_option("--json", *json_path, "write the figures here (rewritten after each patient)");
  cmd->add_option("--cache", *cache, "directory keeping the truth patients and the trained model");
  cmd->add_option("--train", *n_train, "training patients")->default_val(12)->check(CLI::Range(3, 499));
  cmd->add_option("--test", *n_test, "held-out test patients")->default_val(6)->check(CLI::Range(1, 499));
  cmd->add_option("--seed", *seed, "cohort seed")->default_val(3030);
  cmd->add_option("--jobs", *jobs, "patients at once")->default_val(2)->check(CLI::Range(1, 256));
  cmd->add_option("--truth-set", *truth_sets, "name=value for the model simulating the closing frames");
  cmd->add_option("--noise-levels", *levels, "electronic noise SDs of the test renders; the first is the headline")
      ->delimiter(',')
      ->default_str("0.004,0,0.016,0.063,0.25");
  auto model_file = std::make_shared<std::string>();
  cmd->add_option("--model", *model_file,
                  "evaluate this model (mvtwin train-detector) instead of training one; it must not have "
                  "seen a test patient");
  auto train_noise = std::make_shared<std::vector<double>>(kTrainingNoise);
  cmd->add_option("--train-noise", *train_noise, "electronic noise SDs of the training renders (patients cycle)")
      ->delimiter(',')
      ->default_str("0.004,0.016,0.063,0");
  cmd->add_option("--voxel", ro->voxel_mm, "voxel size, mm")->default_val(ro->voxel_mm);
  cmd->add_option("--probe-jitter", ro->probe_jitter_deg, "probe pose variation between patients, degrees")
      ->default_val(ro->probe_jitter_deg);
  cmd->add_option("--speckle", ro->speckle, "speckle, 0 to 1")->default_val(ro->speckle);
  cmd->add_option("--dropout", ro->dropout_fraction, "fraction of beams with a drop-out")
      ->default_val(ro->dropout_fraction);
  cmd->add_option("--trees", dopt->trees, "trees per forest")->default_val(dopt->trees);
  cmd->add_option("--samples", dopt->samples_per_volume, "training samples per volume and detector")
      ->default_val(dopt->samples_per_volume);
  cmd->callback([=, &ctx] {
    ctx.run = [=, &ctx] {
      if (levels->empty()) throw Error("bench detect: --noise-levels needs at least one level");
      for (double l : *train_noise)
        if (!(l >= 0 && l <= 10)) throw Error("bench detect: training noise levels must be 0..10, got " + std::to_string(l));
      for (double l : *levels)
        if (!(l >= 0 && l <= 10)) throw Error("bench detect: noise levels must be 0..10, got " + std::to_string(l));
      {
        detection::TeeRenderOptions check = *ro;
        check.noise = levels->front();
        if (const std::string e = check.invalid(); !e.empty()) throw Error("bench detect: " + e);
        if (const std::string e = dopt->invalid(); !e.empty()) throw Error("bench detect: " + e);
      }
      cv::setNumThreads(1);  // s_per_volume is one core's; patients run --jobs at once
      const VirtualTeeTruth truth(*truth_sets);
      auto render_json = [&](double noise) {
        return json{{"voxel_mm", ro->voxel_mm},         {"box_mm", ro->box_mm},
                    {"sector_deg", ro->sector_deg},     {"probe_depth_mm", ro->probe_depth_mm},
                    {"probe_jitter_deg", ro->probe_jitter_deg}, {"axial_psf_mm", ro->axial_psf_mm},
                    {"lateral_psf_mm", ro->lateral_psf_mm},
                    {"attenuation_db_per_mm", ro->attenuation_db_per_mm},
                    {"dynamic_range_db", ro->dynamic_range_db}, {"speckle", ro->speckle},
                    {"noise", noise},                   {"dropout_fraction", ro->dropout_fraction},
                    {"blood", ro->blood}};
      };
      const json detector_json{{"scales", dopt->scales},
                               {"trees", dopt->trees},
                               {"max_depth", dopt->max_depth},
                               {"samples_per_volume", dopt->samples_per_volume},
                               {"seed", dopt->seed}};
      // The model is named by everything that made it: truths, training renders, detector options.
      const std::string model_key = !model_file->empty() ? "file " + *model_file : cache_key(truth.key + " seed=" + std::to_string(*seed) +
                                              " train=" + std::to_string(*n_train) + " render=" +
                                              render_json(levels->front()).dump() + " " + detector_json.dump() +
                                              " train_noise=" + json(*train_noise).dump());
      auto patient_seed = [&](bool train, int i) {
        return virtual_cohort_seed(*seed, train ? i : 500 + i);  // test patients: 501, 502, ...
      };
      if (!cache->empty()) fs::create_directories(*cache);
      std::mutex io;  // console and HDF5 (not built thread-safe)

      // Resuming: rows of an earlier run with the same setup.
      const json setup{{"seed", *seed},   {"train", *n_train},           {"test", *n_test},
                       {"truth_key", truth.key}, {"model_key", model_key},
                       {"render", render_json(0.0)}};  // the test renders but their noise
      json runs = json::array();
      if (!json_path->empty() && fs::exists(*json_path)) {
        try {
          std::ifstream f(*json_path);
          const json old = json::parse(f);
          if (old.value("setup", json::object()) == setup) runs = old.value("runs", json::array());
        } catch (const std::exception&) {
        }
        if (!runs.empty()) std::cout << "resuming: " << runs.size() << " detections from " << *json_path << "\n";
      }
      auto done = [&](std::uint64_t ps, double noise) {
        for (const auto& r : runs)
          if (r.value("patient_seed", std::uint64_t{0}) == ps && r.value("noise", -1.0) == noise) return true;
        return false;
      };

      detection::TeeRenderOptions train_render = *ro;
      train_render.noise = levels->front();

      // 2. The detector: trained on the training cohort's renders at the headline noise (cached).
      const fs::path model_path = !model_file->empty() ? fs::path(*model_file)
                                  : cache->empty()       ? fs::path()
                                                         : fs::path(*cache) / ("detector_" + model_key + ".yml.gz");
      // A given model: its training patients from its provenance, none of them a test patient.
      std::vector<std::string> given_training;
      if (!model_file->empty()) {
        for (const auto& [name, value] : detection::ValveDetector::provenance(model_path))
          if (name == "training_patients") {
            std::stringstream ss(value.substr(0, value.find(' ')));
            for (std::string id; std::getline(ss, id, ',');) given_training.push_back(id);
          }
        for (int i = 0; i < *n_test; ++i)
          for (const std::string& id : given_training)
            if (id == "virtual-" + std::to_string(patient_seed(false, i)))
              throw Error("bench detect: " + *model_file + " was trained on test patient " + id +
                          " (choose another --seed)");
      }
      std::optional<detection::ValveDetector> detector;
      double train_s = 0;
      int training_volumes = 0;
      std::vector<std::uint64_t> train_seeds;
      for (int i = 0; i < *n_train; ++i) train_seeds.push_back(patient_seed(true, i));
      if (!model_path.empty() && fs::exists(model_path)) {
        detector = detection::ValveDetector::load(model_path);
        std::cout << "detector: " << model_path.string() << " (cached)\n";
      } else {
        VirtualTrainingResult r =
            train_on_virtual_cohort(train_seeds, truth, train_render, *train_noise, *dopt, *jobs, fs::path(*cache), io);
        cv::setNumThreads(1);
        detector = std::move(r.detector);
        train_s = r.train_s;
        training_volumes = r.volumes;
        if (!model_path.empty()) {
          std::string ids;
          for (const auto& id : r.patients) ids += (ids.empty() ? "" : ",") + id;
          detector->save(model_path, {{"mvtwin_version", std::string(kVersion)},
                                      {"command", ctx.command_line},
                                      {"created_utc", utc_now_iso8601()},
                                      {"training_patients", ids},
                                      {"training_volumes", std::to_string(r.volumes)},
                                      {"train_s", std::to_string(train_s)}});
        }
      }

      // 3. The held-out cohort at every noise level.
      auto summary = [&] {
        json curve = json::array();
        json headline;
        for (double l : *levels) {
          std::vector<const json*> rs;
          for (const auto& r : runs)
            if (r.value("noise", -1.0) == l && r.value("ok", false)) rs.push_back(&r);
          if (rs.empty()) continue;
          json s = summarize_detections(rs);
          s["noise"] = l;
          if (headline.is_null() && l == levels->front()) headline = s;
          curve.push_back(s);
        }
        std::vector<std::uint64_t> test_seeds;
        for (int i = 0; i < *n_test; ++i) test_seeds.push_back(patient_seed(false, i));
        json j{{"synthetic", true},
               {"setup", setup},
               {"n_train", model_file->empty() ? json(*n_train) : json(given_training.size())},
               {"n_test", *n_test},
               {"train_patients", model_file->empty() ? json(train_seeds) : json(given_training)},
               {"test_patients", test_seeds},
               {"truth_model", forward::describe_options(truth.closure.simulation)},
               {"render", render_json(levels->front())},
               {"noise_levels", *levels},
               {"train_noise", *train_noise},
               {"detector", detector_json},
               {"detector_file", model_path.string()},
               {"jobs", *jobs},
               {"curve", curve},
               {"runs", runs},
               {"provenance",
                {{"mvtwin_version", kVersion}, {"command", ctx.command_line}, {"created_utc", utc_now_iso8601()}}}};
        if (train_s > 0) j["train_s"] = train_s, j["training_volumes"] = training_volumes;
        if (!headline.is_null()) j.update(headline);  // error_mean_mm, landmark_error_mm, ... at the first level
        return j;
      };
      std::vector<std::pair<double, int>> todo;
      for (double l : *levels)
        for (int i = 0; i < *n_test; ++i)
          if (!done(patient_seed(false, i), l)) todo.emplace_back(l, i);
      std::vector<std::optional<Patient>> test(static_cast<std::size_t>(*n_test));
      std::vector<std::string> test_failed(test.size());
      std::vector<std::once_flag> made(test.size());
      run_jobs(todo.size(), *jobs, [&](std::size_t k) {
        const auto [noise, i] = todo[k];
        const auto ui = static_cast<std::size_t>(i);
        const std::uint64_t ps = patient_seed(false, i);
        json row{{"patient_seed", ps}, {"noise", noise}};
        try {
          std::call_once(made[ui], [&] {
            try {
              test[ui] = virtual_tee_patient(ps, i, truth, fs::path(*cache), io);
            } catch (const Error& e) {
              test_failed[ui] = e.what();
            }
          });
          if (!test[ui]) throw Error(test_failed[ui]);
          const Patient& p = *test[ui];
          detection::TeeRenderOptions o = *ro;
          o.noise = noise;
          const std::vector<ImageVolume> images = render_virtual_tee(p, o);
          std::vector<detection::DetectionInfo> info;
          const std::vector<ValveFrame> det = detector->detect_sequence(images, &info);
          row.update({{"ok", true}, {"id", p.id}, {"pathology", std::string(pathology_name(p.truth->pathology))},
                      {"frames", detection_errors(p, det, info)}});
          const json s = summarize_detections({&row});
          std::lock_guard<std::mutex> lock(io);
          std::printf("noise %-6g patient %d/%d %-28s surface %.2f mm (max frame %.2f), papillary %.2f mm, %.2f s/volume\n",
                      noise, i + 1, *n_test, row["pathology"].get<std::string>().c_str(),
                      s["error_mean_mm"].get<double>(), s["error_max_frame_mm"].get<double>(),
                      s["papillary_error_mm"].get<double>(), s["s_per_volume"].get<double>());
          std::fflush(stdout);
        } catch (const Error& e) {
          row.update({{"ok", false}, {"reason", e.what()}});
          std::lock_guard<std::mutex> lock(io);
          std::cout << "noise " << noise << " patient " << ps << ": " << e.what() << std::endl;
        }
        std::lock_guard<std::mutex> lock(io);
        runs.push_back(row);
        write_json_file(*json_path, summary(), 1);
      });
      const json s = summary();
      write_json_file(*json_path, s, 1);
      std::printf("\n%-8s %8s %6s %18s %12s %12s %14s %12s\n", "noise", "patients", "frames", "surface mm (SD)",
                  "open mm", "closed mm", "papillary mm", "s/volume");
      for (const json& c : s["curve"]) {
        auto phase = [&](const char* name) {
          return c["by_phase"].contains(name) ? c["by_phase"][name]["error_mean_mm"].get<double>() : std::nan("");
        };
        std::printf("%-8g %8d %6d %11.2f (%4.2f) %12.2f %12.2f %14.2f %12.2f\n", c["noise"].get<double>(),
                    c["patients"].get<int>(), c["frames"].get<int>(), c["error_mean_mm"].get<double>(),
                    c["error_sd_mm"].get<double>(), phase("open"), phase("closed"),
                    c["papillary_error_mm"].get<double>(), c["s_per_volume"].get<double>());
      }
      if (s.contains("landmark_error_mm")) {
        std::cout << "\nlandmarks at noise " << levels->front() << " (mm):\n";
        for (const auto& [name, e] : s["landmark_error_mm"].items())
          std::printf("  %-30s %.2f\n", name.c_str(), e.get<double>());
      }
      if (!json_path->empty()) std::cout << "wrote " << *json_path << "\n";
      return 0;
    };
  });
}

}  // namespace mvtwin::tools
