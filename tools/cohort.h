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
  /// Tune each normal patient's marginal chordae until its closure seals (forward/chordae_tuning.h)
  bool tune_normal_chordae = true;
};

int run_cohort(const CohortArgs& args);
void register_cohort(CLI::App& app, Context& ctx);

}  // namespace mvtwin::tools
