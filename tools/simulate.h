#pragma once
// mvtwin simulate: the closure of a patient's valve.
#include <string>
#include <vector>

#include "command.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::tools {

struct SimulateArgs : CommandArgs {
  std::string file;
  std::string out;  ///< result file; "" = none
  std::string vtk;  ///< directory for the ParaView series; "" = none
  bool force = false;
  bool use_detected = false;  ///< the sequence detected from the images (mvtwin detect)
  bool no_contact = false;
  int newton = 1;
  std::string solver = forward::name(forward::ClosureOptions{}.solver.kind);
  forward::ClosureOptions options;
  std::vector<std::string> sets;  ///< name=value for any option or parameter
};

int run_simulate(const SimulateArgs& args);
void register_simulate(CLI::App& app, Context& ctx);

}  // namespace mvtwin::tools
