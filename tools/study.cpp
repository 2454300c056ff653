// mvtwin study NAME: the experiments of studies/, one subcommand each, on one process or over
// the ranks of mpirun (the same numbers either way).
#include <cstdio>
#include <string>

#include <CLI/CLI.hpp>

#include "commands.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/studies/work_pool.h"
#include "one_patient_study.h"
#include "study_clip.h"
#include "study_cohort.h"
#include "study_commands.h"
#include "study_convergence.h"
#include "study_detection.h"
#include "study_robustness.h"
#include "study_sensitivity.h"

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

void add_one_patient_options(CLI::App* cmd, OnePatientStudyArgs* args) {
  cmd->add_option("--out", args->out, "the study folder")->required();
  cmd->add_option("--seed", args->seed, "cohort seed of the virtual patient")->default_val(2026);
  cmd->add_option("--patient", args->patient, "index of the virtual patient in its cohort")
      ->default_val(0)
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--patient-file", args->patient_file, "a patient file instead")
      ->check(CLI::ExistingFile);
  cmd->add_option("--jobs", args->jobs, "simulations at once in each process")
      ->default_val(2)
      ->check(CLI::Range(1, 256));
}

void register_study(CLI::App& app, Context& ctx) {
  auto* study =
      app.add_subcommand("study", "Experiments with reports and plots (on one machine or MPI)");
  study->require_subcommand(1);
  study->footer("Run 'mvtwin study NAME --help' for a study's options and an example.");
  register_study_cohort(study, ctx);
  register_study_sensitivity(study, ctx);
  register_study_convergence(study, ctx);
  register_study_clip(study, ctx);
  register_study_robustness(study, ctx);
  register_study_detection(study, ctx);
}

}  // namespace mvtwin::tools
