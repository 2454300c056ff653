#pragma once
// mvtwin bench import: the segmentation import on label maps of virtual patients.
#include <cstdint>
#include <string>
#include <vector>

#include "command.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::tools {

struct BenchImportArgs : CommandArgs {
  int n = 10;
  unsigned seed = 4040;
  std::string json_path;
  std::vector<double> voxels = std::vector<double>{0.5, 0.8};
  double noise = 0.15;
  /// The model simulating the closed frames.
  std::vector<std::string> closure_sets{"ures=24", "vres=16", "dt=0.01", "layers=1"};
};

int run_bench_import(const BenchImportArgs& args);
void register_bench_import(CLI::App& bench, Context& ctx);

}  // namespace mvtwin::tools
