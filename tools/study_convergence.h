#pragma once
// mvtwin study convergence: the closure over resolution, layers and time step, each run against
// the finest of its series, and time against error (studies/convergence_study.h).
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "one_patient_study.h"

namespace mvtwin::tools {

struct StudyConvergenceArgs : OnePatientStudyArgs {
  bool quick = false;
  std::vector<std::string> sets;
  std::vector<int> ures, vres, layers;
  std::vector<double> dt;
  std::vector<std::string> pair_sets;  ///< the paired runs' settings (default: the study's)
  bool no_pair = false;
};

int run_study_convergence(const StudyConvergenceArgs& args);
void register_study_convergence(CLI::App* study, Context& ctx);

}  // namespace mvtwin::tools
