// mvtwin simulate (tools/simulate.h).
#include "simulate.h"

#include <algorithm>
#include <iostream>

#include "exit_codes.h"
#include "mvtwin/core/error.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/forward/model_vtk.h"
#include "output_files.h"
#include "progress.h"
#include "report.h"

namespace mvtwin::tools {
namespace fs = std::filesystem;

int run_simulate(const SimulateArgs& a) {
  const Patient p = read_patient_for_run(a.file, a.use_detected);
  forward::ClosureOptions o = a.options;
  if (!forward::parse_linear_solver(a.solver, &o.solver.kind))
    throw Error("unknown solver '" + a.solver + "'");
  o.contact.enabled = !a.no_contact;
  o.newton_iterations = a.newton;
  ValveParameters par;
  if (p.truth) par = p.truth->parameters;
  for (const std::string& s : a.sets) forward::apply_setting(s, &o, &par);
  if (o.record_every == 0) o.record_every = std::max(1, static_cast<int>(0.1 / o.dt));
  const fs::path summary_json = a.out.empty() ? fs::path() : summary_path(a.out);
  if (!a.out.empty()) {
    refuse_overwrite(a.out, a.force);
    refuse_overwrite(summary_json, a.force);
  }
  std::cout << "simulating " << p.id << (p.synthetic ? " [SYNTHETIC]" : "") << ": " << o.model.ures
            << " x " << o.model.vres << " grid, " << o.model.layers << " layer(s), dt " << o.dt
            << " s, contact " << (o.contact.enabled ? "on" : "off") << std::endl;
  o.progress = progress_line("  closure");
  const forward::ClosureResult r = forward::simulate_closure(p.sequence, par, o);
  print_closure(r, std::cout);
  if (!a.out.empty()) {
    write_simulation_result(a.out, r, o, par, p, a.file, a.command_line);
    write_json_file(summary_json, simulation_summary_json(r, o, par, p, a.command_line));
    std::cout << "wrote " << a.out << " (mvtwin info " << a.out << ") and " << summary_json.string()
              << "\n";
  }
  if (!a.vtk.empty()) {
    const auto files = forward::export_closure_vtk(r, a.vtk);
    std::cout << "wrote " << files.size() << " files to " << a.vtk
              << " (open simulation.pvd and leaflets_end.vtu)\n";
  }
  return r.summary.converged() ? kExitOk : kExitFailed;
}

void register_simulate(CLI::App& app, Context& ctx) {
  auto* cmd = app.add_subcommand("simulate", "Simulate the closure of a patient");
  cmd->footer(
      "Examples:\n  mvtwin simulate patient.h5 --out closed.h5 --vtk sim/\n"
      "  mvtwin simulate patient.h5 --out closed_dt.h5 --set dt=0.005 --set contact=off\n"
      "  mvtwin simulate patient.h5 --out closed_ref.h5 --solver cholmod-supernodal --set "
      "pcg_tolerance=1e-8   # long: a reference\n"
      "  mvtwin simulate patient.h5 --out closed_at_peak.h5 --set settle_mm=0\n"
      "The third factorizes every step and solves the linear systems to 1e-8: a reference.\n"
      "The closed valve is the valve at rest under the peak pressure: after the closure the load\n"
      "is held until no step moves a node by settle_mm (0.01 mm; at most settle_max_s, 5 s).\n"
      "settle_mm=0 stops when the pressure peaks, as the paper did: 1.3-3.4x faster, and\n"
      "0.04-0.52 mm (mean) from rest on virtual patients 1-5 (docs/forward-status.md).\n"
      "Uses the patient's hidden parameters when it is synthetic, else the defaults.\n"
      "Beside the result, NAME.json: status, settings and the closed valve's regurgitant\n"
      "orifice (aroa_mm2, eroa_mm2, openings_mm2, mr_grade, coaptation_length_mm;\n"
      "docs/regurgitant-orifice.md).\n"
      "Exit status 4 when the simulation fails (the result file says why).");
  auto a = std::make_shared<SimulateArgs>();
  cmd->add_option("FILE", a->file, "patient file (HDF5)")->required();
  cmd->add_option("--out", a->out, "result file (HDF5)");
  cmd->add_flag("--use-detected", a->use_detected,
                "simulate the sequence detected from the images (mvtwin detect)");
  cmd->add_flag("--force", a->force, "replace an existing result file");
  cmd->add_option("--vtk", a->vtk, "directory for the ParaView series");
  add_grid_options(cmd, a->options.model.ures, a->options.model.vres);
  cmd->add_option("--dt", a->options.dt,
                  "time step, s (with error-controlled steps, the default: the smallest)")
      ->default_val(0.01);
  cmd->add_option("--newton", a->newton, "Newton iterations per step (1 = one linearization)")
      ->default_val(1);
  cmd->add_option("--solver", a->solver,
                  "reused-factor-pcg | cholmod-supernodal | cholmod-simplicial | eigen-ldlt")
      ->default_val(a->solver);
  cmd->add_flag("--no-contact", a->no_contact, "switch self-contact off");
  cmd->add_option("--set", a->sets,
                  "name=value for any option or parameter (repeatable), e.g. --set dt=0.005 "
                  "--set peak_pressure_mmhg=100");
  run_on_parse(cmd, ctx, a, run_simulate);
}

}  // namespace mvtwin::tools
