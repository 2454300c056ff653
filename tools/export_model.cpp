// mvtwin export-model (tools/export_model.h).
#include "export_model.h"

#include <iostream>
#include <sstream>

#include "exit_codes.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/version.h"
#include "mvtwin/forward/closure_scene.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/forward/closure_simulation.h"
#include "mvtwin/forward/model_vtk.h"
#include "mvtwin/forward/valve_model.h"
#include "report.h"

namespace mvtwin::tools {

int run_export_model(const ExportModelArgs& a) {
  const Patient p = read_patient(a.file, false);
  forward::ClosureOptions o = a.options;
  ValveParameters par;
  if (p.truth) par = p.truth->parameters;
  for (const std::string& s : a.sets) forward::apply_setting(s, &o, &par);
  const forward::ClosureScene scene = forward::make_closure_scene(p.sequence, par, o);
  std::ostringstream comment;
  comment << "mvtwin " << kVersion << " export-model of " << p.id
          << (p.synthetic ? " [SYNTHETIC: virtual patient]" : "") << "\ncommand: " << a.command_line
          << "\ncreated: " << utc_now_iso8601() << "\nparameters:";
  par.for_each([&](const std::string& name, double v, const char* unit) {
    comment << " " << name << "=" << v << " " << unit << ";";
  });
  std::vector<int> guarded;
  if (a.guard_run) {
    std::cout << "simulating the closure to find the elements the inversion guard holds ..."
              << std::endl;
    const forward::ClosureResult r = forward::simulate_closure(scene, o);
    guarded = r.guarded_elements;
    std::cout << "  " << guarded.size() << " element(s) held by the inversion guard"
              << (r.summary.converged() ? "" : " (the closure failed: " + r.summary.reason + ")")
              << "; valve.feb makes them neo-Hookean\n";
    comment << "\nneo-Hookean (held by mvtwin's inversion guard during the closure): "
            << guarded.size() << " element(s)";
  }
  const auto files = forward::export_scene(scene, o, a.out, comment.str(), guarded);
  const forward::ValveModel& m = scene.model;
  std::cout << "scene of " << p.id << (p.synthetic ? " [SYNTHETIC]" : "") << ": "
            << m.mesh.num_elements()
            << (m.mesh.order == forward::TetOrder::kQuadratic ? " quadratic" : " linear")
            << " tetrahedra, " << m.mesh.num_nodes() << " nodes, " << scene.chordae.size()
            << " chordae, " << scene.springs.size() << " clips, " << scene.prescribed.size()
            << " prescribed nodes, closure over " << fixed(scene.duration(), 3)
            << " s (simulated); worst element quality " << m.min_quality << " (element "
            << m.worst_element << "); wrote " << files.size() << " files to " << a.out
            << " (valve.feb for FEBio)\n";
  return kExitOk;
}

void register_export_model(CLI::App& app, Context& ctx) {
  auto* cmd = app.add_subcommand("export-model",
                                 "Write the FE scene at end-diastole for ParaView and FEBio");
  cmd->footer(
      "Examples:\n  mvtwin export-model patient.h5 --out model/\n"
      "  mvtwin export-model patient.h5 --out model40/ --set ures=40 --set clips=0.25,1,0.75,1 "
      "--no-guard-run\n"
      "Writes leaflets.vtu / leaflets_quadratic.vtu (tags, fibres, prescribed flags), "
      "chordae.vtp\n"
      "(rest lengths and laws), pressure_surface.vtp, boundary.csv (pressure profile, papillary\n"
      "tips), annulus_motion.csv and boundary.pvd (prescribed motion), valve.feb (FEBio 4.0).\n"
      "Uses the patient's hidden parameters when it is synthetic, else the defaults; --set as "
      "in\n"
      "mvtwin simulate.");
  auto a = std::make_shared<ExportModelArgs>();
  cmd->add_option("FILE", a->file, "patient file (HDF5)")->required();
  cmd->add_option("--out", a->out, "output directory")->required();
  add_grid_options(cmd, a->options.model.ures, a->options.model.vres);
  cmd->add_option("--layers", a->options.model.layers, "element layers through the thickness")
      ->default_val(1);
  cmd->add_option("--marginal-chordae", a->options.model.marginal_chordae, "marginal chordae count")
      ->default_val(28);
  cmd->add_option("--set", a->sets, "name=value for any option or parameter (repeatable)");
  cmd->add_flag("!--no-guard-run", a->guard_run,
                "do not simulate the closure first (it finds the elements the inversion guard "
                "holds, neo-Hookean in valve.feb)");
  run_on_parse(cmd, ctx, a, run_export_model);
}

}  // namespace mvtwin::tools
