#pragma once
// mvtwin study clip: the clip plan made on calibrated virtual patients against the truth of their
// hidden parameters (studies/clip_study.h).
#include <cstdint>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "command.h"

namespace mvtwin::tools {

struct StudyClipArgs : CommandArgs {
  std::string out, cache, fit;  // fit: ClipStudyOptions' default unless given
  int patients = 10, jobs = 2, max_scanned = 40, max_simulations = 50;
  std::uint64_t seed = 2026;
  double min_eroa = 20.0;
  std::vector<double> positions;
  std::vector<std::string> devices;
  bool quick = false, no_intervals = false;
  std::vector<std::string> sets;
};

int run_study_clip(const StudyClipArgs& args);
void register_study_clip(CLI::App* study, Context& ctx);

}  // namespace mvtwin::tools
