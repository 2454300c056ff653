// mvtwin study cohort: default-parameter closure and calibration over a cohort (the paper's
// Tables 2-3; studies/cohort_study.h).
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "calibrate.h"
#include "exit_codes.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/studies/cohort_study.h"
#include "mvtwin/studies/report.h"
#include "study_cohort.h"
#include "study_commands.h"

namespace mvtwin::tools {

int run_study_cohort(const StudyCohortArgs& args) {
  studies::CohortStudyOptions o;
  if (args.quick) o = studies::CohortStudyOptions::quick();
  o.out = args.out;
  o.folder = args.folder;
  o.cache = args.cache;
  if (!args.quick || args.given.count("--patients")) o.patients = args.patients;
  o.seed = args.seed;
  o.calibrate = args.quick ? args.given.count("--fit") + args.given.count("--method") > 0 &&
                                 !args.no_calibrate
                           : !args.no_calibrate;
  o.fit = args.fit;
  o.method = args.method;
  o.max_simulations = args.max_sims;
  o.jobs = args.jobs;
  o.observation.noise_mm = args.noise;
  o.rating = args.rating;
  o.restlength_tolerance = args.restlength_tolerance;
  for (const auto& s : args.sets) forward::apply_setting(s, &o.model, &o.defaults);
  // The search model follows calibrate's rule (inverse::search_model_for: 0.8 of the grid in
  // each direction from 25 points around the annulus, else the model itself) unless --fit-set
  // says otherwise.
  o.fit_model = inverse::search_model_for(o.model).value_or(o.model);
  for (const auto& s : args.fit_sets)
    apply_model_setting(s, &o.fit_model, "--fit-set: the calibration fits the parameters");
  for (const auto& s : args.observe_sets)
    apply_model_setting(
        s, &o.observation.simulation,
        "--observe-set: virtual patients are observed with their hidden parameters");
  o.command = args.command_line;
  std::unique_ptr<studies::WorkPool> pool = studies::make_pool_from_environment();
  o.progress = progress_printer(*pool);
  if (pool->is_root())
    std::cout << "cohort study in " << o.out.string() << " on " << pool->describe() << ", "
              << (o.folder.empty() ? std::to_string(o.patients) + " virtual patients (SYNTHETIC)"
                                   : "the patients of " + o.folder.string())
              << (o.calibrate ? ", calibrated" : ", default parameters") << std::endl;
  const studies::CohortStudyResult r = studies::run_cohort_study(o, *pool);
  if (!pool->is_root()) return 0;
  const auto& ov = r.summary["overall"];
  auto ms = [](const nlohmann::json& s) {
    return studies::mean_sd(s["mean"].is_number() ? s["mean"].get<double>() : std::nan(""),
                            s["sd"].is_number() ? s["sd"].get<double>() : std::nan(""));
  };
  std::printf("%-28s %6s %7s %20s %20s   %s\n", "pathology", "n", "failed", "error default mm",
              "error calibrated mm", "satisfactory/passable/unsatisfactory");
  auto row = [&](const std::string& name, const nlohmann::json& v) {
    std::printf("%-28s %6d %7d %20s %20s   %d/%d/%d\n", name.c_str(), v["patients"].get<int>(),
                v["failed"].get<int>(), ms(v["error_default_mm"]).c_str(),
                ms(v["error_calibrated_mm"]).c_str(), v["ratings"]["satisfactory"].get<int>(),
                v["ratings"]["passable"].get<int>(), v["ratings"]["unsatisfactory"].get<int>());
  };
  for (const auto& [k, v] : r.summary["by_pathology"].items()) row(k, v);
  row("all", ov);
  std::printf(
      "paper (25 patients)                                  1.49 ± 0.62                        "
      "  7/9/9\n");
  if (r.summary.contains("calibration")) {
    const auto& c = r.summary["calibration"];
    const auto& rr = c["restlength_recovery"];
    std::printf(
        "calibration (%s): %d patients, %s simulations each (%d failed in all), %s s each; "
        "rest-length factors within %.2f of the truth: %d of %d identified (%d not)\n",
        inverse::fit_method_name(o.method), c["calibrated"].get<int>(),
        ms(c["simulations"]).c_str(), c["failed_simulations"].get<int>(),
        ms(c["calibrate_s"]).c_str(), rr["tolerance"].get<double>(),
        rr["identified_within_tolerance"].get<int>(), rr["identified"].get<int>(),
        rr["unidentified"].get<int>());
  }
  std::cout << "wrote " << (o.out / "study.json").string() << ", study.h5, report.md, report.html ("
            << r.wall_s << " s)\n";
  return ov["failed"].get<int>() > 0 ? int{kExitFailed} : int{kExitOk};
}

void register_study_cohort(CLI::App* study, Context& ctx) {
  auto* cmd = study->add_subcommand(
      "cohort", "Default-parameter closure and calibration over a cohort (the paper's Tables 2-3)");
  cmd->footer(
      "Examples:\n"
      "  mvtwin study cohort --quick --out cohort_quick/\n"
      "  mvtwin study cohort --folder cohort_quick/observed/ --no-calibrate --set ures=20 "
      "--set vres=10 --out folder_study/\n"
      "  mvtwin study cohort --patients 25 --seed 2026 --out cohort25/   # long\n"
      "  mpirun -np 4 mvtwin study cohort --patients 100 --jobs 2 --out cohort100/\n"
      "  mvtwin study cohort --patients 10 --method ceres --cache obs/ --out cohort10_ceres/   "
      "# long\n"
      "Virtual patients are drawn by the rule of every command (mvtwin cohort --seed S makes the\n"
      "same ones); their observed closures (a finer model, --observe-set) are cached in\n"
      "OUT/observed or --cache. Writes OUT/study.json, study.h5, PNG plots and report.md/.html.\n"
      "Resumable: rerun the same command and finished patients are not redone. To compare\n"
      "optimizers, run one study per --method with the same --cache (observations are shared).");
  auto a = std::make_shared<StudyCohortArgs>();
  cmd->add_option("--out", a->out, "the study folder")->required();
  cmd->add_option("--patients", a->patients, "virtual patients")
      ->check(CLI::Range(1, 100000))
      ->default_val(25);
  cmd->add_option("--seed", a->seed, "cohort seed")->default_val(2026);
  cmd->add_option("--folder", a->folder, "every patient file (*.h5) in this folder instead")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--cache", a->cache,
                  "observed closures of virtual patients (default OUT/observed)");
  cmd->add_flag("--no-calibrate", a->no_calibrate, "default parameters only");
  cmd->add_option("--fit", a->fit, "what to calibrate")->default_val(a->fit);
  add_method_option(cmd, &a->method);
  cmd->add_option("--max-sims", a->max_sims, "simulations per calibration")
      ->default_val(50)
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--jobs", a->jobs, "simulations at once in each process")
      ->default_val(2)
      ->check(CLI::Range(1, 256));
  cmd->add_option(
      "--set", a->sets,
      "name=value: the simulation model (ures=20, dt=0.005, ...) or a default parameter");
  cmd->add_option("--fit-set", a->fit_sets,
                  "name=value: the model the calibration searches with before refining on the "
                  "--set model (default: 0.8 of its grid from 25 points around the annulus, as "
                  "calibrate)");
  cmd->add_option("--observe-set", a->observe_sets,
                  "name=value: the virtual patients' observation model");
  cmd->add_option("--noise", a->noise, "observation noise SD, mm")->default_val(0.5);
  cmd->add_option("--restlength-tolerance", a->restlength_tolerance,
                  "a fitted rest-length factor this close to the truth counts as recovered")
      ->default_val(a->restlength_tolerance);
  cmd->add_option("--match-eroa", a->rating.match_mm2,
                  "rating: a simulated EROA this close to the observed one (mm^2) is satisfactory")
      ->default_val(a->rating.match_mm2);
  cmd->add_option("--match-fraction", a->rating.match_fraction,
                  "rating: ... or this fraction of the observed EROA, if larger")
      ->default_val(a->rating.match_fraction);
  cmd->add_flag(
      "--quick", a->quick,
      "the test size: 5 patients, default parameters, a coarse model (flags given still apply)");
  run_on_parse(cmd, ctx, a, run_study_cohort);
}

}  // namespace mvtwin::tools
