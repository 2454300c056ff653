// mvtwin study detection: the valve detector on synthetic TEE of a held-out virtual cohort, with
// its error against image noise (studies/detection_study.h).
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "exit_codes.h"
#include "mvtwin/studies/detection_study.h"
#include "mvtwin/studies/report.h"
#include "study_commands.h"
#include "study_detection.h"

namespace mvtwin::tools {

int run_study_detection(const StudyDetectionArgs& args) {
  studies::DetectionStudyOptions o;
  if (args.quick) o = studies::DetectionStudyOptions::quick();
  o.out = args.out;
  o.cache = args.cache;
  o.model_file = args.model;
  o.seed = args.seed;
  o.jobs = args.jobs;
  if (!args.quick || args.given.count("--train")) o.train = args.train;
  if (!args.quick || args.given.count("--test")) o.test = args.test;
  if (args.given.count("--noise-levels")) o.noise_levels = args.levels;
  if (args.given.count("--train-noise")) o.train_noise = args.train_noise;
  // Flags given replace the defaults (or the quick size's).
  const auto& given_values = args.defaults;
  auto given = [&](const char* flag) { return args.given.count(flag) > 0; };
  if (given("--voxel")) o.render.voxel_mm = given_values.render.voxel_mm;
  if (given("--axial-psf")) o.render.axial_psf_mm = given_values.render.axial_psf_mm;
  if (given("--lateral-psf")) o.render.lateral_psf_mm = given_values.render.lateral_psf_mm;
  if (given("--probe-jitter")) o.render.probe_jitter_deg = given_values.render.probe_jitter_deg;
  if (given("--speckle")) o.render.speckle = given_values.render.speckle;
  if (given("--dropout")) o.render.dropout_fraction = given_values.render.dropout_fraction;
  if (given("--trees")) o.detector.trees = given_values.detector.trees;
  if (given("--samples")) o.detector.samples_per_volume = given_values.detector.samples_per_volume;
  // The truth model takes model options only: a patient parameter would be dropped.
  forward::ClosureOptions scratch;
  for (const auto& s : args.truth_sets)
    apply_model_setting(s, &scratch, "--truth-set: the truth uses each patient's own");
  for (const auto& s : args.truth_sets) o.truth_sets.push_back(s);
  o.command = args.command_line;
  std::unique_ptr<studies::WorkPool> pool = studies::make_pool_from_environment();
  o.progress = progress_printer(*pool);
  const studies::DetectionStudyResult r = studies::run_detection_study(o, *pool);
  if (!pool->is_root()) return 0;
  std::printf("%-8s %8s %6s %20s %9s %9s %9s %13s %10s\n", "noise", "patients", "frames",
              "surface mm (SD)", "open", "closing", "closed", "papillary mm", "s/volume");
  auto num = [](const nlohmann::json& j, const char* k) {
    return j.contains(k) && j[k].is_number() ? j[k].get<double>() : std::nan("");
  };
  for (const auto& c : r.curve) {
    auto phase = [&](const char* p) {
      return c["by_phase"].contains(p) ? num(c["by_phase"][p], "error_mean_mm") : std::nan("");
    };
    std::printf("%-8g %8d %6d %20s %9.2f %9.2f %9.2f %13.2f %10.2f\n", c["noise"].get<double>(),
                c["patients"].get<int>(), c["frames"].get<int>(),
                studies::mean_sd(num(c, "error_mean_mm"), num(c, "error_sd_mm")).c_str(),
                phase("open"), phase("closing"), phase("closed"), num(c, "papillary_error_mm"),
                num(c, "s_per_volume"));
  }
  std::printf("paper (real TEE, 200 volumes)   %20s %42s %10s   [these: SYNTHETIC]\n",
              "2.75 ± 0.86", "", "4.8");
  int failed = 0;
  for (const auto& run : r.runs) failed += !run.ok;
  std::cout << "wrote " << (o.out / "report.md").string() << ", study.json, study.h5 (" << r.wall_s
            << " s)\n";
  return failed > 0 ? int{kExitFailed} : int{kExitOk};
}

void register_study_detection(CLI::App* study, Context& ctx) {
  auto* cmd = study->add_subcommand(
      "detection", "Valve detection from synthetic 3D+t TEE on a held-out virtual cohort");
  cmd->footer(
      "Examples:\n"
      "  mvtwin study detection --quick --out det_quick/\n"
      "  mvtwin study detection --model detector.yml.gz --test 1 --voxel 2.5 --truth-set ures=16 "
      "--truth-set vres=8 --out det_model/   # long: minutes\n"
      "  mvtwin study detection --out detection/   # long: about 25 min on 2 cores\n"
      "Two disjoint virtual cohorts of --seed (pathologies in turn): their closing frames are\n"
      "simulated without noise (--truth-set; the truth to detect) and every frame is rendered as\n"
      "synthetic TEE (--voxel, --*-psf, --probe-jitter, --speckle, --dropout). A detector is "
      "trained on\n"
      "the first --train patients (renders cycling through --train-noise), or --model is used\n"
      "(refused if it saw a test patient), and run on the --test patients at each --noise-levels\n"
      "(the first is the headline). Writes OUT/study.json, study.h5 (one row per frame), PNG\n"
      "plots and report.md/.html. Truths and the detector are cached in OUT/cache or --cache.\n"
      "Resumable; more --test patients or noise levels extend a finished study.");
  auto a = std::make_shared<StudyDetectionArgs>();
  auto& d = a->defaults;
  cmd->add_option("--out", a->out, "the study folder")->required();
  cmd->add_option("--cache", a->cache, "truths and trained detectors (default OUT/cache)");
  cmd->add_option("--train", a->train, "training patients")
      ->default_val(12)
      ->check(CLI::Range(3, 500));
  cmd->add_option("--test", a->test, "held-out test patients")
      ->default_val(6)
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--seed", a->seed, "cohort seed")->default_val(3030);
  cmd->add_option("--jobs", a->jobs, "patients at once in each process")
      ->default_val(2)
      ->check(CLI::Range(1, 256));
  cmd->add_option("--truth-set", a->truth_sets,
                  "name=value for the model simulating the closing frames (ures=40, ...)");
  cmd->add_option("--noise-levels", a->levels,
                  "electronic noise SDs of the test renders; the first is the headline")
      ->delimiter(',')
      ->default_str("0.004,0,0.016,0.063,0.25");
  cmd->add_option("--train-noise", a->train_noise,
                  "electronic noise SDs of the training renders (patients cycle)")
      ->delimiter(',')
      ->default_str("0.004,0.016,0.063,0");
  cmd->add_option("--model", a->model,
                  "evaluate this detector (mvtwin train-detector) instead of training one")
      ->check(CLI::ExistingFile);
  cmd->add_option("--voxel", d.render.voxel_mm, "voxel size, mm")->default_val(d.render.voxel_mm);
  cmd->add_option("--axial-psf", d.render.axial_psf_mm, "point-spread SD along the beam, mm")
      ->default_val(d.render.axial_psf_mm);
  cmd->add_option("--lateral-psf", d.render.lateral_psf_mm,
                  "point-spread SD across the beam at the probe depth, mm")
      ->default_val(d.render.lateral_psf_mm);
  cmd->add_option("--probe-jitter", d.render.probe_jitter_deg,
                  "probe pose variation between patients, degrees")
      ->default_val(d.render.probe_jitter_deg);
  cmd->add_option("--speckle", d.render.speckle, "speckle, 0 to 1")->default_val(d.render.speckle);
  cmd->add_option("--dropout", d.render.dropout_fraction, "fraction of beams with a drop-out")
      ->default_val(d.render.dropout_fraction);
  cmd->add_option("--trees", d.detector.trees, "trees per forest")->default_val(d.detector.trees);
  cmd->add_option("--samples", d.detector.samples_per_volume,
                  "training samples per volume and detector")
      ->default_val(d.detector.samples_per_volume);
  cmd->add_flag("--quick", a->quick,
                "the test size: 3 training and 1 test patient, coarse images, small forests");
  run_on_parse(cmd, ctx, a, run_study_detection);
}

}  // namespace mvtwin::tools
