#pragma once
// mvtwin render-tee: synthetic 3D+t TEE of a patient's valve sequence.
#include <cstdint>
#include <string>
#include <vector>

#include "command.h"
#include "mvtwin/detection/tee_renderer.h"

namespace mvtwin::tools {

struct RenderTeeArgs : CommandArgs {
  std::string file;
  std::string out;
  std::string export_dir;
  std::string png;
  bool force = false;
  detection::TeeRenderOptions render;
};

int run_render_tee(const RenderTeeArgs& args);
void register_render_tee(CLI::App& app, Context& ctx);

}  // namespace mvtwin::tools
