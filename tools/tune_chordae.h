#pragma once
// mvtwin tune-chordae: a virtual patient's marginal chordae sized so that its simulated
// closure seals (forward/chordae_tuning.h).
#include <string>
#include <vector>

#include "command.h"

namespace mvtwin::tools {

struct TuneChordaeArgs : CommandArgs {
  std::string file;               ///< the patient file
  std::string out;                ///< the tuned patient file
  bool force = false;             ///< replace an existing --out
  int iterations = 12;            ///< length updates
  double shortest = 0.7;          ///< x each chorda's length at least
  double gain = 1.0;              ///< mm of length per mm of gap above the seal
  double reach_sites = 2.5;       ///< the rule's half-width, insertion sites of 28
  double longest = 1.3;           ///< x each chorda's length at most
  std::vector<std::string> sets;  ///< name=value for the closures it simulates
};

int run_tune_chordae(const TuneChordaeArgs& args);
void register_tune_chordae(CLI::App& app, Context& ctx);

}  // namespace mvtwin::tools
