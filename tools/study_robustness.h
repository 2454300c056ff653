#pragma once
// mvtwin study robustness: randomized abuse of the simulator, every outcome classified
// (studies/robustness_study.h).
#include <cstdint>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "command.h"

namespace mvtwin::tools {

struct StudyRobustnessArgs : CommandArgs {
  std::string out;
  int runs = 200, jobs = 2;
  std::uint64_t seed = 7;
  bool quick = false;
  std::vector<std::string> sets;
};

int run_study_robustness(const StudyRobustnessArgs& args);
void register_study_robustness(CLI::App* study, Context& ctx);

}  // namespace mvtwin::tools
