#pragma once
// mvtwin study clip: the residual orifice before and after the best single clip and pair over a
// cohort (studies/clip_study.h).
#include <cstdint>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "command.h"

namespace mvtwin::tools {

struct StudyClipArgs : CommandArgs {
  std::string out, folder;
  int patients = 10, jobs = 2;
  std::uint64_t seed = 2026;
  std::vector<double> positions;
  double spacing = 0.2, margin = 1.0;
  bool quick = false, no_pairs = false;
  std::vector<std::string> sets;
};

int run_study_clip(const StudyClipArgs& args);
void register_study_clip(CLI::App* study, Context& ctx);

}  // namespace mvtwin::tools
