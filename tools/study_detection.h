#pragma once
// mvtwin study detection: the valve detector on synthetic TEE of a held-out virtual cohort, with
// its error against image noise (studies/detection_study.h).
#include <cstdint>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "command.h"
#include "mvtwin/studies/detection_study.h"

namespace mvtwin::tools {

struct StudyDetectionArgs : CommandArgs {
  std::string out, cache, model;
  int train = 12, test = 6, jobs = 2;
  std::uint64_t seed = 3030;
  bool quick = false;
  std::vector<double> levels, train_noise;
  std::vector<std::string> truth_sets;
  studies::DetectionStudyOptions defaults;
};

int run_study_detection(const StudyDetectionArgs& args);
void register_study_detection(CLI::App* study, Context& ctx);

}  // namespace mvtwin::tools
