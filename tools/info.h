#pragma once
// mvtwin info: a human summary of a patient or simulation file.
#include <string>

#include "command.h"

namespace mvtwin::tools {

struct InfoArgs : CommandArgs {
  std::string file;
};

int run_info(const InfoArgs& args);
void register_info(CLI::App& app, Context& ctx);

}  // namespace mvtwin::tools
