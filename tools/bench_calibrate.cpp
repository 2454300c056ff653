// mvtwin bench calibrate: automatic calibration over a virtual cohort of mixed pathology,
// NLopt and Ceres side by side (figures, not tests).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <algorithm>
#include <atomic>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "jobs.h"
#include "output_files.h"
#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/version.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/forward/virtual_closure.h"
#include "mvtwin/inverse/calibration.h"

namespace mvtwin::tools {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

void save_json(const std::string& path, const json& j) { write_json_file(path, j, 1); }

}  // namespace

void register_bench_calibrate(CLI::App& bench, Context& ctx) {
  auto* cmd = bench.add_subcommand("calibrate", "Calibration over a virtual cohort");
  cmd->footer(
      "Example:\n  mvtwin bench calibrate --patients 10 --json calibrate.json --cache obs/\n"
      "Patients are drawn with the pathologies in turn (normal, elongated chordae, ruptured\n"
      "chordae, functional MR, stiff leaflets); their closing frames are simulated by the\n"
      "observation model (--observe-set; cached in --cache) with detection-like noise; each is\n"
      "then calibrated by every --methods from the defaults. Resumable from its JSON.");
  auto json_path = std::make_shared<std::string>();
  auto cache = std::make_shared<std::string>();
  auto n = std::make_shared<int>(10);
  auto seed = std::make_shared<unsigned>(2026);
  auto fit = std::make_shared<std::string>("restlength,stiffness,pressure");
  auto methods = std::make_shared<std::vector<std::string>>(std::vector<std::string>{"bobyqa", "ceres"});
  auto sets = std::make_shared<std::vector<std::string>>();
  auto observe = std::make_shared<std::vector<std::string>>();
  auto noise = std::make_shared<double>(0.5);
  auto co = std::make_shared<inverse::CalibrationOptions>();
  auto observe_only = std::make_shared<bool>(false);
  cmd->add_option("--json", *json_path, "write the figures here (rewritten after each fit)");
  cmd->add_option("--cache", *cache, "directory keeping the observed virtual patients");
  cmd->add_option("--patients", *n, "number of virtual patients")->default_val(10)->check(CLI::Range(1, 10000));
  cmd->add_option("--seed", *seed, "cohort seed")->default_val(2026);
  cmd->add_option("--fit", *fit, "what to fit")->default_val("restlength,stiffness,pressure");
  cmd->add_option("--methods", *methods, "optimizers to compare")->default_str("bobyqa ceres");
  cmd->add_option("--set", *sets, "name=value for the calibration model");
  cmd->add_option("--observe-set", *observe,
                  "name=value for the observation model (default: the fine model of "
                  "mvtwin phantom --simulate-closure)");
  cmd->add_option("--noise", *noise, "observation noise SD, mm")->default_val(0.5);
  add_fit_options(cmd, co.get());
  cmd->add_flag("--observe-only", *observe_only,
                "only simulate the observed closures into --cache (--jobs patients at once)");
  cmd->callback([=, &ctx] {
    ctx.run = [=, &ctx] {
      forward::ClosureOptions model;
      ValveParameters defaults;
      for (const auto& a : *sets) forward::apply_setting(a, &model, &defaults);
      forward::VirtualClosureOptions vo;
      vo.noise_mm = *noise;
      {
        ValveParameters unused;
        for (const auto& a : *observe) forward::apply_setting(a, &vo.simulation, &unused);
      }
      json runs = json::array();
      if (!json_path->empty() && fs::exists(*json_path)) {
        try {
          std::ifstream f(*json_path);
          const json old = json::parse(f);
          if (old.value("seed", 0u) == *seed && old.value("fit", "") == *fit &&
              old.value("settings", json::array()) == json(*sets) &&
              old.value("observe_settings", json::array()) == json(*observe))
            runs = old.value("runs", json::array());
        } catch (const std::exception&) {
        }
        if (!runs.empty()) std::cout << "resuming: " << runs.size() << " fits from " << *json_path << "\n";
      }
      auto done = [&](std::uint64_t ps, const std::string& m) {
        for (const auto& r : runs)
          if (r.value("patient_seed", std::uint64_t{0}) == ps && r.value("method", "") == m) return true;
        return false;
      };
      auto summary = [&] {
        json by_method = json::object();
        for (const std::string& m : *methods) {
          double before = 0, after = 0, noise_sum = 0, wall = 0, wall_max = 0, rl_abs = 0;
          int k = 0, sims = 0, failed = 0, ok = 0, rl_ident = 0, rl_within = 0, rl_unident = 0;
          for (const auto& r : runs) {
            if (r.value("method", "") != m) continue;
            ++k;
            if (!r.value("ok", false)) continue;
            ++ok;
            before += r["error_before_mm"].get<double>();
            after += r["error_after_mm"].get<double>();
            noise_sum += r["noise_mm"].get<double>();
            wall += r["wall_s"].get<double>();
            sims += r["sims"].get<int>();
            failed += r["failed_sims"].get<int>();
            wall_max = std::max(wall_max, r["wall_s"].get<double>());
            // Rest-length factors: the target is 0.05 of the truth where the data identify them.
            for (const auto& [name, err] : r["param_error"].items()) {
              if (name.rfind("restlength_factor_", 0) != 0) continue;
              if (!r["identified"].value(name, false)) {
                ++rl_unident;
                continue;
              }
              ++rl_ident;
              rl_abs += std::abs(err.get<double>());
              if (std::abs(err.get<double>()) <= 0.05) ++rl_within;
            }
          }
          if (ok == 0) continue;
          by_method[m] = {{"fits", k},
                          {"succeeded", ok},
                          {"error_before_mm", before / ok},
                          {"error_after_mm", after / ok},
                          {"noise_mm", noise_sum / ok},
                          {"error_after_over_noise", after / noise_sum},
                          {"wall_s_mean", wall / ok},
                          {"wall_s_max", wall_max},
                          {"restlength_identified", rl_ident},
                          {"restlength_identified_within_0.05", rl_within},
                          {"restlength_identified_abs_error_mean", rl_ident ? rl_abs / rl_ident : 0.0},
                          {"restlength_unidentified", rl_unident},
                          {"sims_mean", static_cast<double>(sims) / ok},
                          {"failed_sims", failed}};
        }
        return json{{"patients", *n},
                    {"seed", *seed},
                    {"fit", *fit},
                    {"methods", *methods},
                    {"settings", *sets},
                    {"observe_settings", *observe},
                    {"observation_model", forward::describe_options(vo.simulation)},
                    {"calibration_model", forward::describe_options(model)},
                    {"noise_mm", *noise},
                    {"jobs", co->jobs},
                    {"max_sims", co->max_simulations},
                    {"synthetic", true},
                    {"overall", by_method},
                    {"runs", runs},
                    {"provenance",
                     {{"mvtwin_version", kVersion},
                      {"command", ctx.command_line},
                      {"created_utc", utc_now_iso8601()}}}};
      };
      if (!cache->empty()) fs::create_directories(*cache);
      auto patient_seed = [&](int i) { return cohort_member(*seed, i).seed; };
      // The cache key holds the observation model and the noise, so that a changed --observe-set
      // or --noise never reuses an observation made otherwise.
      std::string description = "noise=" + std::to_string(*noise);
      for (const auto& [name, value] : forward::describe_options(vo.simulation))
        description += " " + name + "=" + value;
      const std::string key = cache_key(description);
      auto cache_path = [&](std::uint64_t ps) {
        return cache->empty() ? fs::path()
                              : fs::path(*cache) / ("observed_" + std::to_string(ps) + "_" + key + ".h5");
      };
      // A patient's observed closure (the observation model plus noise); throws mvtwin::Error.
      auto observe_patient = [&](int i) {
        Patient p = make_cohort_patient(*seed, i);
        forward::simulate_observed_closure(&p, vo);
        return p;
      };
      // Patients whose observation failed (reason), and how long observations took (s).
      std::map<int, std::string> unobservable;
      std::map<int, double> observe_seconds;
      // Phase 1: the observed closures missing from the cache, --jobs patients at once (each
      // simulation is single-threaded, and concurrent simulations are bit-identical to serial ones).
      if (!cache->empty()) {
        std::vector<int> todo;
        for (int i = 0; i < *n; ++i)
          if (!fs::exists(cache_path(patient_seed(i)))) todo.push_back(i);
        std::mutex out;
        run_jobs(todo.size(), co->jobs, [&](std::size_t k) {
          const int i = todo[k];
          const std::uint64_t ps = patient_seed(i);
          const auto t0 = std::chrono::steady_clock::now();
          {
            std::lock_guard<std::mutex> lock(out);
            std::cout << "patient " << i + 1 << "/" << *n << " ("
                      << pathology_name(static_cast<Pathology>(i % kNumPathologies))
                      << "): simulating its observed closure ..." << std::endl;
          }
          try {
            const Patient p = observe_patient(i);
            const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
            std::lock_guard<std::mutex> lock(out);  // also serializes HDF5 (not built thread-safe)
            write_patient(cache_path(ps), p);
            observe_seconds[i] = s;
            std::cout << "patient " << i + 1 << "/" << *n << ": observed in " << s << " s -> "
                      << cache_path(ps).string() << std::endl;
          } catch (const Error& e) {
            std::lock_guard<std::mutex> lock(out);
            unobservable[i] = e.what();
            std::cout << "patient " << i + 1 << "/" << *n << ": no observation (" << e.what()
                      << "); the fits will skip it" << std::endl;
          }
        });
      } else if (*observe_only) {
        throw Error("bench calibrate: --observe-only needs --cache DIR");
      }
      if (*observe_only) return 0;
      for (int i = 0; i < *n; ++i) {
        const std::uint64_t ps = patient_seed(i);
        bool all_done = true;
        for (const auto& m : *methods) all_done = all_done && done(ps, m);
        if (all_done) continue;
        Patient p;
        const fs::path cached = cache_path(ps);
        const auto t0 = std::chrono::steady_clock::now();
        try {
          if (unobservable.count(i)) throw Error(unobservable[i]);  // phase 1 tried already
          if (!cached.empty()) {
            p = read_patient(cached, false);
          } else {
            std::cout << "patient " << i + 1 << "/" << *n << " ("
                      << pathology_name(static_cast<Pathology>(i % kNumPathologies))
                      << "): simulating its observed closure ..." << std::endl;
            p = observe_patient(i);
          }
        } catch (const Error& e) {
          std::cout << "patient " << ps << ": no observation (" << e.what() << "); skipped\n";
          for (const auto& m : *methods)
            runs.push_back({{"patient_seed", ps}, {"method", m}, {"ok", false}, {"reason", e.what()}});
          save_json(*json_path, summary());
          continue;
        }
        // The observation's own time: from phase 1, or here (a cached one read: its read time).
        const double observe_s = observe_seconds.count(i)
                                     ? observe_seconds[i]
                                     : std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        for (const std::string& m : *methods) {
          if (done(ps, m)) continue;
          json row{{"patient_seed", ps},
                   {"pathology", std::string(pathology_name(p.truth->pathology))},
                   {"method", m},
                   {"observe_s", observe_s}};
          try {
            inverse::ObjectiveOptions oo;
            oo.simulation = model;
            inverse::ClosureObjective obj(p, inverse::ParameterSpace(*fit, defaults), oo);
            inverse::CalibrationOptions o = *co;
            o.method = m;
            const inverse::CalibrationResult r = inverse::calibrate(obj, o);
            const Eigen::VectorXd truth = obj.space().values_of(p.truth->parameters);
            json perr = json::object(), ident = json::object();
            for (int k = 0; k < obj.space().size(); ++k) {
              perr[obj.space().specs()[k].name] = r.fitted[k] - truth[k];
              ident[obj.space().specs()[k].name] = static_cast<bool>(r.identified[k]);
            }
            row.update({{"ok", true},
                        {"error_before_mm", r.error_before_mm},
                        {"error_after_mm", r.error_after_mm},
                        {"noise_mm", *noise},
                        {"param_error", perr},
                        {"identified", ident},
                        {"sd", std::vector<double>(r.sd.data(), r.sd.data() + r.sd.size())},
                        {"sims", r.simulations},
                        {"failed_sims", r.failed_simulations},
                        {"wall_s", r.wall_s},
                        {"termination", r.termination}});
            std::printf("patient %d/%d %-28s %-7s error %.3f -> %.3f mm (noise %.2f), %d sims (%d failed), %.1f s\n",
                        i + 1, *n, std::string(pathology_name(p.truth->pathology)).c_str(), m.c_str(),
                        r.error_before_mm, r.error_after_mm, *noise, r.simulations,
                        r.failed_simulations, r.wall_s);
            std::fflush(stdout);
          } catch (const Error& e) {
            row.update({{"ok", false}, {"reason", e.what()}});
            std::cout << "patient " << ps << " " << m << ": " << e.what() << "\n";
          }
          runs.push_back(row);
          save_json(*json_path, summary());
        }
      }
      const json s = summary();
      save_json(*json_path, s);
      std::printf("%-8s %5s %22s %11s %10s %12s %12s %28s\n", "method", "fits", "error before->after mm",
                  "after/noise", "sims mean", "wall mean s", "wall max s", "rest lengths within 0.05");
      for (const auto& [m, o] : s["overall"].items()) {
        char within[64];
        std::snprintf(within, sizeof within, "%d/%d identified (%d not)",
                      o["restlength_identified_within_0.05"].get<int>(),
                      o["restlength_identified"].get<int>(), o["restlength_unidentified"].get<int>());
        std::printf("%-8s %5d %13.3f -> %5.3f %11.2f %10.1f %12.1f %12.1f %28s\n", m.c_str(),
                    o["succeeded"].get<int>(), o["error_before_mm"].get<double>(),
                    o["error_after_mm"].get<double>(), o["error_after_over_noise"].get<double>(),
                    o["sims_mean"].get<double>(), o["wall_s_mean"].get<double>(),
                    o["wall_s_max"].get<double>(), within);
      }
      if (!json_path->empty()) std::cout << "wrote " << *json_path << "\n";
      return 0;
    };
  });
}

}  // namespace mvtwin::tools
