#pragma once
// mvtwin distance: the point-to-mesh distance between two leaflet (LA) surfaces.
#include <string>

#include "command.h"

namespace mvtwin::tools {

struct DistanceArgs : CommandArgs {
  std::string a, b;                ///< patient or simulation files
  int frame_a = -1, frame_b = -1;  ///< -1: the first closed frame, else 0
  bool json = false;               ///< print JSON at full precision (for scripts)
};

int run_distance(const DistanceArgs& args);
void register_distance(CLI::App& app, Context& ctx);

}  // namespace mvtwin::tools
