#pragma once
// mvtwin study convergence: the closure over resolution, layers and time step, each run against
// the finest of its series, and time against error (studies/convergence_study.h).
#include <cstdint>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "command.h"

namespace mvtwin::tools {

struct StudyConvergenceArgs : CommandArgs {
  std::string out, patient_file;
  std::uint64_t seed = 2026;
  int patient = 0, jobs = 2;
  bool quick = false;
  std::vector<std::string> sets;
  std::vector<int> ures, vres, layers;
  std::vector<double> dt;
};

int run_study_convergence(const StudyConvergenceArgs& args);
void register_study_convergence(CLI::App* study, Context& ctx);

}  // namespace mvtwin::tools
