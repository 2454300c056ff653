#pragma once
// mvtwin export-model: the finite-element scene at end-diastole for ParaView and FEBio.
#include <string>
#include <vector>

#include "command.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::tools {

struct ExportModelArgs : CommandArgs {
  std::string file;
  std::string out;  ///< directory
  forward::ClosureOptions options;
  std::vector<std::string> sets;  ///< name=value for any option or parameter
  /// Simulate the closure first to find the elements the inversion guard holds (neo-Hookean in
  /// valve.feb).
  bool guard_run = true;
};

int run_export_model(const ExportModelArgs& args);
void register_export_model(CLI::App& app, Context& ctx);

}  // namespace mvtwin::tools
