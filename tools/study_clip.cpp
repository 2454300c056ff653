// mvtwin study clip: the clip plan made on calibrated virtual patients against the truth of their
// hidden parameters on the fine model (studies/clip_study.h).
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "exit_codes.h"
#include "mvtwin/inverse/calibration.h"
#include "mvtwin/studies/clip_study.h"
#include "mvtwin/studies/report.h"
#include "study_clip.h"
#include "study_commands.h"

namespace mvtwin::tools {

int run_study_clip(const StudyClipArgs& args) {
  studies::ClipStudyOptions o;
  if (args.quick) o = studies::ClipStudyOptions::quick();
  o.out = args.out;
  o.cache = args.cache;
  auto given = [&](const char* name) { return !args.quick || args.given.count(name) > 0; };
  if (given("--patients")) o.patients = args.patients;
  if (given("--min-eroa")) o.min_eroa_mm2 = args.min_eroa;
  if (given("--max-scanned")) o.max_scanned = args.max_scanned;
  if (given("--max-simulations")) o.max_simulations = args.max_simulations;
  // Only when given (its default_val is for --help; CLI11 does not assign it): an empty --fit is
  // then refused like calibrate's, not taken for "the default".
  if (args.given.count("--fit")) o.fit = args.fit;
  o.seed = args.seed;
  if (!args.positions.empty()) o.positions = args.positions;
  if (!args.devices.empty()) o.devices = args.devices;
  o.intervals = !args.no_intervals;
  o.jobs = args.jobs;
  o.command = args.command_line;
  for (const auto& s : args.sets)
    apply_model_setting(s, &o.model, "--set: the study calibrates the parameters");
  if (!args.sets.empty())  // the search model follows the prediction model (calibrate's rule)
    o.fit_model = args.quick ? o.model : inverse::search_model_for(o.model).value_or(o.model);
  std::unique_ptr<studies::WorkPool> pool = studies::make_pool_from_environment();
  o.progress = progress_printer(*pool);
  if (pool->is_root())
    std::cout << "clip study in " << o.out.string() << " on " << pool->describe() << ": the first "
              << o.patients << " virtual patients (SYNTHETIC) of cohort seed " << o.seed
              << " with a true EROA >= " << o.min_eroa_mm2 << " mm^2, " << o.num_options()
              << " options each" << std::endl;
  const studies::ClipStudyResult r = studies::run_clip_study(o, *pool);
  if (!pool->is_root()) return 0;
  const nlohmann::json& s = r.summary;
  auto count = [&](const char* a, const char* b) {
    return std::to_string(s[a].get<int>()) + " of " + std::to_string(s[b].get<int>());
  };
  auto num = [&](const char* a) {
    return s[a].is_number() ? studies::number(s[a].get<double>(), 1) : std::string("n/a");
  };
  std::cout << "EROA within tolerance: calibrated "
            << count("eroa_within_tolerance", "eroa_compared") << ", default "
            << count("eroa_default_within_tolerance", "eroa_compared") << "; mean |error| "
            << num("eroa_mean_abs_error_mm2") << " vs " << num("eroa_default_mean_abs_error_mm2")
            << " mm^2\n"
            << "MVA within tolerance: " << count("mva_within_tolerance", "mva_compared") << "\n"
            << "truth's best option in the predicted top two: "
            << count("best_true_in_predicted_top2", "patients_ranked") << " (default "
            << count("best_true_in_default_top2", "patients_ranked") << ")\n"
            << "truth inside the best option's 95 % interval: "
            << count("truth_in_best_interval", "best_intervals") << "\n";
  if (static_cast<int>(r.patients.size()) < o.patients)
    std::cout << "only " << r.patients.size() << " of the first " << r.scanned.size()
              << " members qualified (--patients " << o.patients << "; raise --max-scanned)\n";
  std::cout << "wrote " << (o.out / "report.md").string() << " (" << r.wall_s << " s)\n";
  const bool failed = s["patients_failed"].get<int>() > 0 ||
                      s["truth_options_failed"].get<int>() > 0 ||
                      s["predicted_options_failed"].get<int>() > 0 ||
                      static_cast<int>(r.patients.size()) < o.patients;
  return failed ? int{kExitFailed} : int{kExitOk};
}

void register_study_clip(CLI::App* study, Context& ctx) {
  auto* cmd = study->add_subcommand(
      "clip", "The clip plan on calibrated virtual patients against the truth");
  cmd->footer(
      "Examples:\n"
      "  mvtwin study clip --quick --patients 1 --no-intervals --out clip_quick/\n"
      "  mvtwin study clip --out clip/   # long: hours on 2 cores\n"
      "  mpirun -np 4 mvtwin study clip --patients 20 --out clip20/\n"
      "Takes the first --patients virtual patients of cohort --seed whose true EROA (their\n"
      "observed closure on the fine model) is at least --min-eroa. Truth: each option (every\n"
      "--devices at every --positions) simulated with the hidden parameters on that fine model\n"
      "and opened in diastole. Prediction: the same option on the model calibrated (--fit:\n"
      "rest lengths, chordae stiffness, pressure and the leaflets' moduli) from the noisy\n"
      "observed frames, with 95 % intervals from the calibration; and at the default\n"
      "parameters. Writes study.json, study.h5, a plot and report.md/.html, the calibrations in\n"
      "calibrations/ and the observations in observed/ (or --cache). Resumable: every\n"
      "observation, calibration and simulation is kept. Exit 3 when anything failed.");
  auto a = std::make_shared<StudyClipArgs>();
  cmd->add_option("--out", a->out, "the study folder")->required();
  cmd->add_option("--patients", a->patients, "qualifying virtual patients")
      ->check(CLI::Range(1, 100000))
      ->default_val(10);
  cmd->add_option("--seed", a->seed, "cohort seed")->default_val(2026);
  cmd->add_option("--min-eroa", a->min_eroa, "a patient qualifies from this true EROA, mm^2")
      ->check(CLI::Range(0.0, 1000.0))
      ->default_val(20.0);
  cmd->add_option("--max-scanned", a->max_scanned, "cohort members looked at, at most")
      ->check(CLI::Range(1, 100000))
      ->default_val(40);
  cmd->add_option("--devices", a->devices,
                  "devices of the options (forward/data/clip_devices.json)")
      ->delimiter(',')
      ->default_str("NT,XTW");
  cmd->add_option("--positions", a->positions, "positions along the coaptation line, in (0, 1)")
      ->delimiter(',')
      ->default_str("0.35,0.5,0.65");
  cmd->add_option("--fit", a->fit,
                  "what the calibration fits (groups or names, as mvtwin calibrate --fit)")
      ->default_val(studies::ClipStudyOptions{}.fit);
  cmd->add_option("--max-simulations", a->max_simulations, "the calibration's budget")
      ->check(CLI::Range(1, 100000))
      ->default_val(50);
  cmd->add_option("--cache", a->cache, "where observed closures are kept (default OUT/observed)");
  cmd->add_flag("--no-intervals", a->no_intervals, "no intervals from the calibration");
  cmd->add_option("--jobs", a->jobs, "simulations at once in each process")
      ->default_val(2)
      ->check(CLI::Range(1, 256));
  cmd->add_option("--set", a->sets, "name=value: the prediction model (ures=20, dt=0.005, ...)");
  cmd->add_flag("--quick", a->quick,
                "the test size: the first 2 members, coarse models, the XTW at 0.5");
  run_on_parse(cmd, ctx, a, run_study_clip);
}

}  // namespace mvtwin::tools
