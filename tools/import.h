#pragma once
// mvtwin import: a patient from segmentations, meshes and landmarks made in other tools.
#include <cstdint>
#include <string>
#include <vector>

#include "command.h"
#include "mvtwin/detection/patient_import.h"

namespace mvtwin::tools {

struct ImportArgs : CommandArgs {
  std::vector<std::string> frames;
  std::vector<std::string> sequences;
  std::vector<std::string> markups;
  std::vector<std::string> meshes;
  std::string mesh_space;
  std::vector<std::string> order;
  std::string out;
  std::string json_out;
  std::string convention;
  std::vector<int> labels;
  int papillary = 0;
  std::vector<double> atrium;
  bool no_ring = false;
  bool force = false;
  detection::PatientImportOptions options;
  std::vector<std::string> ruptures;
};

int run_import(const ImportArgs& args);
void register_import(CLI::App& app, Context& ctx);

}  // namespace mvtwin::tools
