#pragma once
// mvtwin cohort: many virtual (synthetic) patients, resumable.
#include <cstdint>
#include <string>

#include "command.h"
#include "mvtwin/core/virtual_patient.h"

namespace mvtwin::tools {

struct CohortArgs : CommandArgs {
  int n = 25;
  std::uint64_t seed = 1;
  std::string out;  ///< directory
  VirtualPatientOptions patient;
};

int run_cohort(const CohortArgs& args);
void register_cohort(CLI::App& app, Context& ctx);

}  // namespace mvtwin::tools
