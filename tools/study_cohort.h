#pragma once
// mvtwin study cohort: default-parameter closure and calibration over a cohort (the paper's
// Tables 2-3; studies/cohort_study.h).
#include <cstdint>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "command.h"
#include "mvtwin/inverse/calibration.h"
#include "mvtwin/studies/cohort_study.h"

namespace mvtwin::tools {

struct StudyCohortArgs : CommandArgs {
  std::string out, folder, cache, fit = "restlength,stiffness,pressure";
  inverse::FitMethod method = inverse::FitMethod::kBobyqa;
  int patients = 25, jobs = 2, max_sims = 50;
  std::uint64_t seed = 2026;
  double noise = 0.5, restlength_tolerance = 0.05;
  bool quick = false, no_calibrate = false;
  std::vector<std::string> sets, fit_sets, observe_sets;
  studies::ClosureRating rating;
};

int run_study_cohort(const StudyCohortArgs& args);
void register_study_cohort(CLI::App* study, Context& ctx);

}  // namespace mvtwin::tools
