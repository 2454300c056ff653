// mvtwin study NAME: the experiments of studies/, one subcommand each, on one process or over
// the ranks of mpirun (the same numbers either way).
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "calibrate.h"
#include "commands.h"
#include "exit_codes.h"
#include "mvtwin/core/error.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/studies/cohort_study.h"
#include "mvtwin/studies/report.h"
#include "mvtwin/studies/sensitivity_study.h"
#include "mvtwin/studies/work_pool.h"
#include "study_commands.h"

namespace mvtwin::tools {
/// A progress line per event on stderr, prefixed by the rank under MPI.
studies::StudyProgress progress_printer(const studies::WorkPool& pool) {
  const std::string prefix = pool.size() > 1 ? "[rank " + std::to_string(pool.rank()) + "] " : "";
  return [prefix](const studies::StudyEvent& e) {
    std::fprintf(stderr, "%s[%s %d/%d] %s\n", prefix.c_str(), e.stage.c_str(), e.done, e.total,
                 e.message.c_str());
    std::fflush(stderr);
  };
}

/// Applies a name=value model option; refuses a patient parameter (naming why) instead of
/// dropping it.
void apply_model_setting(const std::string& assignment, forward::ClosureOptions* options,
                         const std::string& why) {
  forward::apply_option(assignment, options, why);
}

namespace {

void register_cohort(CLI::App* study, Context& ctx) {
  auto* cmd = study->add_subcommand(
      "cohort", "Default-parameter closure and calibration over a cohort (the paper's Tables 2-3)");
  cmd->footer(
      "Examples:\n"
      "  mvtwin study cohort --quick --out cohort_quick/\n"
      "  mvtwin study cohort --folder cohort_quick/observed/ --no-calibrate --out folder_study/\n"
      "  mvtwin study cohort --patients 25 --seed 2026 --out cohort25/   # long\n"
      "  mpirun -np 4 mvtwin study cohort --patients 100 --jobs 2 --out cohort100/\n"
      "  mvtwin study cohort --patients 10 --method ceres --cache obs/ --out cohort10_ceres/   "
      "# long\n"
      "Virtual patients are drawn by the rule of every command (mvtwin cohort --seed S makes the\n"
      "same ones); their observed closures (a finer model, --observe-set) are cached in\n"
      "OUT/observed or --cache. Writes OUT/study.json, study.h5, PNG plots and report.md/.html.\n"
      "Resumable: rerun the same command and finished patients are not redone. To compare\n"
      "optimizers, run one study per --method with the same --cache (observations are shared).");
  struct Args {
    std::string out, folder, cache, fit = "restlength,stiffness,pressure";
    inverse::FitMethod method = inverse::FitMethod::kBobyqa;
    int patients = 25, jobs = 2, max_sims = 50;
    std::uint64_t seed = 2026;
    double noise = 0.5, restlength_tolerance = 0.05;
    bool quick = false, no_calibrate = false;
    std::vector<std::string> sets, fit_sets, observe_sets;
    studies::ClosureRating rating;
  };
  auto a = std::make_shared<Args>();
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
                  "name=value: the model the calibration searches with (default ures=20 on the "
                  "--set model's other options)");
  cmd->add_option("--observe-set", a->observe_sets,
                  "name=value: the virtual patients' observation model");
  cmd->add_option("--noise", a->noise, "observation noise SD, mm")->default_val(0.5);
  cmd->add_option("--restlength-tolerance", a->restlength_tolerance,
                  "a fitted rest-length factor this close to the truth counts as recovered")
      ->default_val(a->restlength_tolerance);
  cmd->add_option("--satisfactory-orifice", a->rating.satisfactory_orifice_mm2,
                  "rating threshold, mm^2")
      ->default_val(a->rating.satisfactory_orifice_mm2);
  cmd->add_option("--satisfactory-coaptation", a->rating.satisfactory_coaptation_mm,
                  "rating threshold, mm")
      ->default_val(a->rating.satisfactory_coaptation_mm);
  cmd->add_option("--unsatisfactory-orifice", a->rating.unsatisfactory_orifice_mm2,
                  "rating threshold, mm^2")
      ->default_val(a->rating.unsatisfactory_orifice_mm2);
  cmd->add_flag(
      "--quick", a->quick,
      "the test size: 5 patients, default parameters, a coarse model (flags given still apply)");
  cmd->callback([=, &ctx] {
    ctx.run = [=, &ctx] {
      studies::CohortStudyOptions o;
      if (a->quick) o = studies::CohortStudyOptions::quick();
      o.out = a->out;
      o.folder = a->folder;
      o.cache = a->cache;
      if (!a->quick || cmd->count("--patients")) o.patients = a->patients;
      o.seed = a->seed;
      o.calibrate = a->quick ? cmd->count("--fit") + cmd->count("--method") > 0 && !a->no_calibrate
                             : !a->no_calibrate;
      o.fit = a->fit;
      o.method = a->method;
      o.max_simulations = a->max_sims;
      o.jobs = a->jobs;
      o.observation.noise_mm = a->noise;
      o.rating = a->rating;
      o.restlength_tolerance = a->restlength_tolerance;
      for (const auto& s : a->sets) forward::apply_setting(s, &o.model, &o.defaults);
      // The search model is the reporting model at 20 x 30 unless --fit-set says otherwise (the
      // quick size searches on its own coarse model).
      if (!a->quick) {
        const int vres = o.model.model.vres;
        o.fit_model = o.model;
        o.fit_model.model.ures = studies::CohortStudyOptions::default_fit_model().model.ures;
        o.fit_model.model.vres = vres;
      } else {
        o.fit_model = o.model;
      }
      for (const auto& s : a->fit_sets)
        apply_model_setting(s, &o.fit_model, "--fit-set: the calibration fits the parameters");
      for (const auto& s : a->observe_sets)
        apply_model_setting(
            s, &o.observation.simulation,
            "--observe-set: virtual patients are observed with their hidden parameters");
      o.command = ctx.command_line;
      std::unique_ptr<studies::WorkPool> pool = studies::make_pool_from_environment();
      o.progress = progress_printer(*pool);
      if (pool->is_root())
        std::cout << "cohort study in " << o.out.string() << " on " << pool->describe() << ", "
                  << (o.folder.empty()
                          ? std::to_string(o.patients) + " virtual patients (SYNTHETIC)"
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
      std::cout << "wrote " << (o.out / "study.json").string()
                << ", study.h5, report.md, report.html (" << r.wall_s << " s)\n";
      return ov["failed"].get<int>() > 0 ? int{kExitFailed} : int{kExitOk};
    };
  });
}

void register_sensitivity(CLI::App* study, Context& ctx) {
  auto* cmd = study->add_subcommand(
      "sensitivity",
      "Annulus and papillary motion, chordae count, stiffness and rest lengths (paper Sec. 4.2)");
  cmd->footer(
      "Examples:\n"
      "  mvtwin study sensitivity --quick --out sens_quick/\n"
      "  mvtwin study sensitivity --out sensitivity/   # long\n"
      "  mvtwin study sensitivity --patient-file patient.h5 --set ures=40 --out sens_p/   # long\n"
      "One patient (index --patient of the virtual cohort --seed, its hidden parameters as the\n"
      "baseline; or --patient-file at the defaults) simulated 11 times: baseline, annulus fixed,\n"
      "papillary tips fixed, 56/20/16/12 marginal chordae, chordae stiffness and rest lengths\n"
      "+-30 %. Writes the tips' distance to the annulus plane over time (plots), the largest\n"
      "difference from the baseline next to the paper's, study.json, study.h5, report.md/.html.");
  struct Args {
    std::string out, patient_file;
    std::uint64_t seed = 2026;
    int patient = 0, jobs = 2;
    double sample_s = 0.01;
    bool quick = false;
    std::vector<std::string> sets;
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("--out", a->out, "the study folder")->required();
  cmd->add_option("--seed", a->seed, "cohort seed of the virtual patient")->default_val(2026);
  cmd->add_option("--patient", a->patient, "index of the virtual patient in its cohort")
      ->default_val(0)
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--patient-file", a->patient_file, "a patient file instead")
      ->check(CLI::ExistingFile);
  cmd->add_option("--sample", a->sample_s, "tip distances every this much image time, s")
      ->default_val(0.01);
  cmd->add_option("--jobs", a->jobs, "simulations at once in each process")
      ->default_val(2)
      ->check(CLI::Range(1, 256));
  cmd->add_option("--set", a->sets, "name=value for the baseline model (ures=40, dt=0.005, ...)");
  cmd->add_flag("--quick", a->quick, "the test size: a coarse model (16 x 12, dt 0.02 s)");
  cmd->callback([=, &ctx] {
    ctx.run = [=, &ctx] {
      studies::SensitivityStudyOptions o;
      if (a->quick) o = studies::SensitivityStudyOptions::quick();
      o.out = a->out;
      o.seed = a->seed;
      o.patient = a->patient;
      o.patient_file = a->patient_file;
      o.sample_s = a->sample_s;
      o.jobs = a->jobs;
      o.command = ctx.command_line;
      for (const auto& s : a->sets)
        apply_model_setting(
            s, &o.model,
            "--set: the baseline is the patient's own (the study varies the chordae itself)");
      std::unique_ptr<studies::WorkPool> pool = studies::make_pool_from_environment();
      o.progress = progress_printer(*pool);
      const studies::SensitivityStudyResult r = studies::run_sensitivity_study(o, *pool);
      if (!pool->is_root()) return 0;
      std::printf("%-26s %14s %14s %16s\n", "case", "max AL diff mm", "max PL diff mm",
                  "end orifice mm2");
      int failed = 0;
      for (const auto& k : r.cases) {
        if (k.status != "ok") {
          ++failed;
          std::printf("%-26s failed: %s\n", k.label.c_str(), k.reason.c_str());
          continue;
        }
        std::printf("%-26s %14.2f %14.2f %16.1f\n", k.label.c_str(), k.max_anterior_diff_mm,
                    k.max_posterior_diff_mm, k.end_orifice_mm2);
      }
      std::cout << "patient " << r.patient_id << (r.synthetic ? " [SYNTHETIC]" : "") << "; wrote "
                << (o.out / "report.md").string() << " (" << r.wall_s << " s)\n";
      return failed ? int{kExitFailed} : int{kExitOk};
    };
  });
}

}  // namespace

void register_study(CLI::App& app, Context& ctx) {
  auto* study =
      app.add_subcommand("study", "Experiments with reports and plots (on one machine or MPI)");
  study->require_subcommand(1);
  study->footer("Run 'mvtwin study NAME --help' for a study's options and an example.");
  register_cohort(study, ctx);
  register_sensitivity(study, ctx);
  register_study_convergence(study, ctx);
  register_study_clip(study, ctx);
  register_study_robustness(study, ctx);
  register_study_detection(study, ctx);
}

}  // namespace mvtwin::tools
