// mvtwin study sensitivity: annulus and papillary motion, chordae count, stiffness and rest
// lengths (the paper's Sec. 4.2; studies/sensitivity_study.h).
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "exit_codes.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/studies/report.h"
#include "mvtwin/studies/sensitivity_study.h"
#include "study_commands.h"
#include "study_sensitivity.h"

namespace mvtwin::tools {

int run_study_sensitivity(const StudySensitivityArgs& args) {
  studies::SensitivityStudyOptions o;
  if (args.quick) o = studies::SensitivityStudyOptions::quick();
  o.out = args.out;
  o.seed = args.seed;
  o.patient = args.patient;
  o.patient_file = args.patient_file;
  o.sample_s = args.sample_s;
  o.jobs = args.jobs;
  o.command = args.command_line;
  for (const auto& s : args.sets)
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
}

void register_study_sensitivity(CLI::App* study, Context& ctx) {
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
  auto a = std::make_shared<StudySensitivityArgs>();
  add_one_patient_options(cmd, a.get());
  cmd->add_option("--sample", a->sample_s, "tip distances every this much image time, s")
      ->default_val(0.01);
  cmd->add_option("--set", a->sets, "name=value for the baseline model (ures=40, dt=0.005, ...)");
  cmd->add_flag("--quick", a->quick, "the test size: a coarse model (16 x 12, dt 0.02 s)");
  run_on_parse(cmd, ctx, a, run_study_sensitivity);
}

}  // namespace mvtwin::tools
