#pragma once
// mvtwin export: a patient file as VTK for ParaView, or as label maps and markups.
#include <string>
#include <vector>

#include "command.h"
#include "mvtwin/detection/label_map.h"

namespace mvtwin::tools {

struct ExportArgs : CommandArgs {
  std::string file;
  std::string vtk;       ///< directory for VTK; "" = none
  std::string labelmap;  ///< directory for label maps and markups; "" = none
  std::string convention = "mvtool";
  detection::LabelMapOptions label_map;
  std::vector<int> frames;  ///< empty = every frame with leaflets
  bool force = false;
  bool sequence = false;  ///< one 3D+t labels.seq.nrrd instead of a file per frame
};

int run_export(const ExportArgs& args);
void register_export(CLI::App& app, Context& ctx);

}  // namespace mvtwin::tools
