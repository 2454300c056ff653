#pragma once
// mvtwin phantom: one virtual (synthetic) patient.
#include <cstdint>
#include <string>
#include <vector>

#include "command.h"
#include "mvtwin/core/virtual_patient.h"

namespace mvtwin::tools {

struct PhantomArgs : CommandArgs {
  std::uint64_t seed = 1;
  std::string out;
  std::string pathology;  ///< a pathology name; "" = drawn from the seed
  VirtualPatientOptions patient;
  bool force = false;
  /// Fill the closing frames by a simulation with the hidden parameters (plus noise).
  bool simulate_closure = false;
  /// That simulation on a coarse model (20 x 10, one layer, dt 0.01 s) instead of the fine one.
  bool quick = false;
  std::vector<std::string> closure_sets;  ///< name=value for that simulation
  double noise_mm = 0.5;
  /// Tune a normal valve's marginal chordae until its closure seals (on the patient's grid;
  /// with --quick on the quick closure's).
  bool tune_normal_chordae = true;
};

int run_phantom(const PhantomArgs& args);
void register_phantom(CLI::App& app, Context& ctx);

}  // namespace mvtwin::tools
