#pragma once
// mvtwin study sensitivity: annulus and papillary motion, chordae count, stiffness and rest
// lengths (the paper's Sec. 4.2; studies/sensitivity_study.h).
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "one_patient_study.h"

namespace mvtwin::tools {

struct StudySensitivityArgs : OnePatientStudyArgs {
  double sample_s = 0.01;
  bool quick = false;
  std::vector<std::string> sets;
};

int run_study_sensitivity(const StudySensitivityArgs& args);
void register_study_sensitivity(CLI::App* study, Context& ctx);

}  // namespace mvtwin::tools
