// mvtwin study convergence: the closure over resolution, layers and time step, each run against
// the finest of its series, and time against error (studies/convergence_study.h).
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "exit_codes.h"
#include "mvtwin/core/error.h"
#include "mvtwin/studies/convergence_study.h"
#include "mvtwin/studies/report.h"
#include "study_commands.h"
#include "study_convergence.h"

namespace mvtwin::tools {

int run_study_convergence(const StudyConvergenceArgs& args) {
  studies::ConvergenceStudyOptions o;
  if (args.quick) o = studies::ConvergenceStudyOptions::quick();
  o.out = args.out;
  o.seed = args.seed;
  o.patient = args.patient;
  o.patient_file = args.patient_file;
  o.jobs = args.jobs;
  o.command = args.command_line;
  if (!args.ures.empty()) o.ures = args.ures;
  if (!args.vres.empty()) o.vres = args.vres;
  if (!args.layers.empty()) o.layers = args.layers;
  if (!args.dt.empty()) o.dt = args.dt;
  if (args.no_pair && !args.pair_sets.empty())
    throw Error("study convergence: --no-pair and --pair-set contradict each other");
  if (args.no_pair) o.pair.clear();
  if (!args.pair_sets.empty()) o.pair = args.pair_sets;
  for (const auto& s : args.sets)
    apply_model_setting(s, &o.model,
                        "--set: the study simulates the patient with its own parameters");
  std::unique_ptr<studies::WorkPool> pool = studies::make_pool_from_environment();
  o.progress = progress_printer(*pool);
  const studies::ConvergenceStudyResult r = studies::run_convergence_study(o, *pool);
  if (!pool->is_root()) return 0;
  const bool paired = !o.pair.empty();
  std::printf("%-7s %-18s %8s %7s %7s %14s %9s %9s%s\n", "factor", "value", "wall_s", "steps",
              "dofs", "error mm", "p95 mm", "max mm",
              paired ? "   paired: wall_s  error mm  max mm  apart mm" : "");
  int failed = 0;
  for (const auto& k : r.runs) {
    if (k.status != "ok") {
      ++failed;
      std::printf("%-7s %-18s failed: %s\n", k.factor.c_str(), k.value.c_str(), k.reason.c_str());
      continue;
    }
    std::printf("%-7s %-18s %8.1f %7d %7d %14s %9.3f %9.3f", k.factor.c_str(),
                (k.value + (k.reference ? " (reference)" : "")).c_str(), k.wall_s, k.steps, k.dofs,
                studies::mean_sd(k.error_mean_mm, k.error_sd_mm, 3).c_str(), k.error_p95_mm,
                k.error_max_mm);
    if (paired && k.paired_status == "ok")
      std::printf("   %14.1f%s %9.3f %7.3f %9.3f", k.paired_wall_s,
                  k.paired_static_converged ? " " : "*", k.paired_error_mean_mm,
                  k.paired_error_max_mm, k.paired_difference_mm);
    else if (paired)
      std::printf("   paired run failed: %s", k.paired_reason.c_str());
    std::printf("\n");
  }
  std::cout << "patient " << r.patient_id << (r.synthetic ? " [SYNTHETIC]" : "") << "; "
            << r.simulations << " simulations; wrote " << (o.out / "report.md").string() << " ("
            << r.wall_s << " s)\n";
  return failed ? int{kExitFailed} : int{kExitOk};
}

void register_study_convergence(CLI::App* study, Context& ctx) {
  auto* cmd = study->add_subcommand(
      "convergence",
      "In-plane and radial resolution, layers and time step against the finest run (paper Sec. "
      "4.1)");
  cmd->footer(
      "Examples:\n"
      "  mvtwin study convergence --quick --out conv_quick/\n"
      "  mvtwin study convergence --out convergence/   # long\n"
      "  mvtwin study convergence --dt 0.01,0.001 --ures 30,40 --out conv_dt/   # long\n"
      "One patient (index --patient of the virtual cohort --seed with its hidden parameters, or\n"
      "--patient-file at the defaults); one factor at a time around the base model (the paper's\n"
      "grid, --set to change it): ures 20,30,40,50, vres 10,20,30, layers 1,2,3, dt 0.1 to\n"
      "1e-4 s. The last value of each series is its reference. Writes the errors next to the\n"
      "paper's, a plot per series, the time-against-error (Pareto) plot, study.json, study.h5\n"
      "and report.md/.html. Resumable; the base model is simulated once for every series.\n"
      "Each model is paired with the same settings plus --pair-set (by default\n"
      "static_rest=on: the closed valve at rest by the static solve beside settling), measured\n"
      "against the same references; --no-pair runs the series alone.");
  auto a = std::make_shared<StudyConvergenceArgs>();
  add_one_patient_options(cmd, a.get());
  cmd->add_option("--set", a->sets, "name=value for the base model (pcg_tolerance=1e-4, ...)");
  cmd->add_option("--ures", a->ures, "in-plane series, coarse to fine")->delimiter(',');
  cmd->add_option("--vres", a->vres, "radial series, coarse to fine")->delimiter(',');
  cmd->add_option("--layers", a->layers, "layer series, coarse to fine")->delimiter(',');
  cmd->add_option("--dt", a->dt, "time-step series, s, coarse to fine")->delimiter(',');
  cmd->add_option("--pair-set", a->pair_sets,
                  "name=value added for each model's paired run (repeatable; replaces the "
                  "default static_rest=on)");
  cmd->add_flag("--no-pair", a->no_pair, "no paired runs");
  cmd->add_flag("--quick", a->quick,
                "the test size: a 12 x 8 base at dt 0.02 s, two or three values per series");
  run_on_parse(cmd, ctx, a, run_study_convergence);
}

}  // namespace mvtwin::tools
