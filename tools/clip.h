#pragma once
// mvtwin clip: the closure after an edge-to-edge clip, at given sites or the best ones found.
#include <string>
#include <vector>

#include "command.h"

namespace mvtwin::tools {

struct ClipArgs : CommandArgs {
  std::string file;
  std::string params;
  std::string at;
  std::string device = "XTW";
  std::vector<std::string> devices;
  std::string out;
  std::string vtk;
  std::string report;
  bool suggest = false;
  bool pairs = false;
  int open_best = 5;
  bool no_intervals = false;
  bool force = false;
  int jobs = 2;
  std::vector<std::string> sets;
  bool use_detected = false;
  bool true_params = false;
};

int run_clip(const ClipArgs& args);
void register_clip(CLI::App& app, Context& ctx);

}  // namespace mvtwin::tools
