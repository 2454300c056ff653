#pragma once
// What the studies of one patient (study convergence, study sensitivity) take alike.
#include <cstdint>
#include <string>

#include <CLI/CLI.hpp>

#include "command.h"

namespace mvtwin::tools {

/// The patient (index --patient of the virtual cohort --seed, or --patient-file), the study
/// folder and the simulations at once.
struct OnePatientStudyArgs : CommandArgs {
  std::string out, patient_file;
  std::uint64_t seed = 2026;
  int patient = 0, jobs = 2;
};

/// Registers --out (required), --seed, --patient, --patient-file and --jobs (tools/study.cpp).
void add_one_patient_options(CLI::App* cmd, OnePatientStudyArgs* args);

}  // namespace mvtwin::tools
