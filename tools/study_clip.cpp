// mvtwin study clip: over a cohort, the residual orifice before and after the best single clip
// and the best pair, how often two clips win, the clip gaps (studies/clip_study.h).
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "exit_codes.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/studies/clip_study.h"
#include "mvtwin/studies/report.h"
#include "study_clip.h"
#include "study_commands.h"

namespace mvtwin::tools {

int run_study_clip(const StudyClipArgs& args) {
  studies::ClipStudyOptions o;
  if (args.quick) o = studies::ClipStudyOptions::quick();
  o.out = args.out;
  o.folder = args.folder;
  if (!args.quick || args.given.count("--patients")) o.patients = args.patients;
  o.seed = args.seed;
  if (!args.positions.empty()) o.positions = args.positions;
  if (!args.quick || args.given.count("--pair-spacing")) o.pair_spacing = args.spacing;
  o.pairs = !args.no_pairs;
  o.two_clip_margin_mm2 = args.margin;
  o.jobs = args.jobs;
  o.command = args.command_line;
  for (const auto& s : args.sets) {
    if (args.folder.empty())
      apply_model_setting(s, &o.model,
                          "--set: virtual patients are simulated with their hidden parameters");
    else
      forward::apply_setting(s, &o.model, &o.defaults);
  }
  std::unique_ptr<studies::WorkPool> pool = studies::make_pool_from_environment();
  o.progress = progress_printer(*pool);
  if (pool->is_root())
    std::cout << "clip study in " << o.out.string() << " on " << pool->describe() << ", "
              << (o.folder.empty() ? std::to_string(o.patients) + " virtual patients (SYNTHETIC)"
                                   : "the patients of " + o.folder.string())
              << ", " << o.candidates().size() + 1 << " closures each" << std::endl;
  const studies::ClipStudyResult r = studies::run_clip_study(o, *pool);
  if (!pool->is_root()) return 0;
  auto st = [](const nlohmann::json& s) {
    return s["mean"].is_number()
               ? studies::mean_sd(s["mean"].get<double>(),
                                  s["sd"].is_number() ? s["sd"].get<double>() : std::nan(""), 1)
               : std::string("n/a");
  };
  std::printf("%-24s %4s %6s %16s %16s %16s %10s\n", "pathology", "n", "failed", "no clip mm2",
              "best single mm2", "best pair mm2", "2 clips win");
  auto row = [&](const std::string& name, const nlohmann::json& v) {
    std::printf("%-24s %4d %6d %16s %16s %16s %10d\n", name.c_str(), v["patients"].get<int>(),
                v["failed"].get<int>(), st(v["orifice_before_mm2"]).c_str(),
                st(v["orifice_best_single_mm2"]).c_str(), st(v["orifice_best_pair_mm2"]).c_str(),
                v["two_clips_win"].get<int>());
  };
  for (const auto& [k, v] : r.summary["by_pathology"].items()) row(k, v);
  row("all", r.summary["overall"]);
  std::cout << "wrote " << (o.out / "report.md").string() << " (" << r.wall_s << " s)\n";
  return r.summary["overall"]["failed"].get<int>() > 0 ? int{kExitFailed} : int{kExitOk};
}

void register_study_clip(CLI::App* study, Context& ctx) {
  auto* cmd = study->add_subcommand(
      "clip", "Residual orifice after the best single clip and pair over a cohort");
  cmd->footer(
      "Examples:\n"
      "  mvtwin study clip --quick --out clip_quick/\n"
      "  mvtwin study clip --out clip/   # long\n"
      "  mpirun -np 4 mvtwin study clip --patients 100 --out clip100/\n"
      "  mvtwin study clip --folder cohort/ --out clip_folder/   # long\n"
      "Virtual patients (--patients of the cohort --seed, drawn as by every command) are\n"
      "simulated with their hidden parameters; patient files (--folder) at the defaults. Each\n"
      "closes without a clip, with a single clip at every --positions value and with every pair\n"
      "of them at least --pair-spacing apart (free edges). Writes the residual orifice before\n"
      "and after, how often two clips win, the clip gaps, plots, study.json, study.h5 and\n"
      "report.md/.html. Resumable: every finished simulation is kept.");
  auto a = std::make_shared<StudyClipArgs>();
  cmd->add_option("--out", a->out, "the study folder")->required();
  cmd->add_option("--patients", a->patients, "virtual patients")
      ->check(CLI::Range(1, 100000))
      ->default_val(10);
  cmd->add_option("--seed", a->seed, "cohort seed")->default_val(2026);
  cmd->add_option("--folder", a->folder, "every patient file (*.h5) in this folder instead")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--positions", a->positions,
                  "single-clip positions along the coaptation line, in (0, 1)")
      ->delimiter(',')
      ->default_str("0.2,0.3,0.4,0.5,0.6,0.7,0.8");
  cmd->add_option("--pair-spacing", a->spacing, "smallest distance between a pair's clips")
      ->default_val(0.2);
  cmd->add_flag("--no-pairs", a->no_pairs, "single clips only");
  cmd->add_option("--two-clip-margin", a->margin,
                  "two clips win when they leave at least this much less orifice, mm^2")
      ->default_val(1.0);
  cmd->add_option("--jobs", a->jobs, "simulations at once in each process")
      ->default_val(2)
      ->check(CLI::Range(1, 256));
  cmd->add_option("--set", a->sets,
                  "name=value: the model (ures=20, dt=0.005, ...) or, for --folder, a default "
                  "parameter");
  cmd->add_flag("--quick", a->quick,
                "the test size: 2 patients, a coarse model, clips at 0.3, 0.5, 0.7 and the pair "
                "0.3 + 0.7");
  run_on_parse(cmd, ctx, a, run_study_clip);
}

}  // namespace mvtwin::tools
