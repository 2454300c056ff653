// Every command on one CLI::App (tools/commands.h), in the order of a session: make or import
// a patient, look at it, simulate, calibrate, clip; then detection, benchmarks and studies.
#include "commands.h"

#include "bench.h"
#include "calibrate.h"
#include "clip.h"
#include "cohort.h"
#include "detect.h"
#include "distance.h"
#include "export.h"
#include "export_model.h"
#include "import.h"
#include "info.h"
#include "phantom.h"
#include "render_tee.h"
#include "simulate.h"
#include "tune_chordae.h"

namespace mvtwin::tools {

void add_commands(CLI::App& app, Context& ctx) {
  register_phantom(app, ctx);
  register_cohort(app, ctx);
  register_info(app, ctx);
  register_export(app, ctx);
  register_export_model(app, ctx);
  register_simulate(app, ctx);
  register_distance(app, ctx);
  register_tune_chordae(app, ctx);
  register_bench(app, ctx);
  register_calibrate(app, ctx);
  register_clip(app, ctx);
  register_render_tee(app, ctx);
  register_detect(app, ctx);
  register_import(app, ctx);
  register_study(app, ctx);
}

}  // namespace mvtwin::tools
