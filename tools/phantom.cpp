// mvtwin phantom (tools/phantom.h).
#include "phantom.h"
#include "report.h"

#include <iostream>

#include "exit_codes.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/forward/virtual_closure.h"

namespace mvtwin::tools {

namespace {

/// The closing frames of --quick: a coarse model, for trying the commands in seconds.
const std::vector<std::string> kQuickClosure = {"ures=20", "vres=10", "layers=1", "dt=0.01",
                                                "pcg_tolerance=0.1"};

}  // namespace

int run_phantom(const PhantomArgs& a) {
  refuse_overwrite(a.out, a.force);
  VirtualPatientOptions o = a.patient;
  if (!a.pathology.empty()) o.pathology = pathology_from_name(a.pathology);
  o.command = a.command_line;
  Patient p = make_virtual_patient(a.seed, o);
  // A healthy valve closes: its chordae sized on the patient's grid (--quick: the quick
  // closure's 20 x 10, for trying the commands in seconds).
  tune_normal_if_asked(&p, a.tune_normal_chordae, a.quick ? 20 : o.ures, a.quick ? 10 : o.vres);
  if (a.simulate_closure) {
    forward::VirtualClosureOptions vo;
    vo.noise_mm = a.noise_mm;
    std::vector<std::string> sets = a.closure_sets;
    if (a.quick) sets.insert(sets.begin(), kQuickClosure.begin(), kQuickClosure.end());
    for (const auto& s : sets)
      forward::apply_option(s, &vo.simulation,
                            "--closure-set: the closing frames are simulated with the patient's "
                            "hidden parameters");
    std::cout << "simulating the closing frames of " << p.id << " ..." << std::endl;
    forward::simulate_observed_closure(&p, vo);
    std::cout << p.truth->closed_frames << "\n";
    if (p.truth->closed_orifice)
      std::cout << "closed valve: " << orifice_line(*p.truth->closed_orifice) << "\n";
  }
  write_patient(a.out, p);
  std::cout << "wrote " << a.out << ": virtual patient " << p.id << " ("
            << pathology_name(p.truth->pathology) << ", " << p.sequence.num_frames()
            << " frames, SYNTHETIC)\n";
  return kExitOk;
}

void register_phantom(CLI::App& app, Context& ctx) {
  auto* cmd = app.add_subcommand("phantom", "Make one virtual (synthetic) patient");
  cmd->footer(
      "Examples:\n"
      "  mvtwin phantom --seed 4 --out patient.h5\n"
      "  mvtwin phantom --seed 7 --pathology functional_mr --out fmr.h5\n"
      "  mvtwin phantom --seed 3 --pathology normal --out closing.h5   # long: its chordae tuned\n"
      "  mvtwin phantom --seed 3 --pathology normal --no-tune-normal-chordae --out normal.h5\n"
      "  mvtwin phantom --seed 1 --simulate-closure --quick --out observed.h5\n"
      "  mvtwin phantom --seed 1 --simulate-closure --out observed_fine.h5   # long: a fine model\n"
      "Without --simulate-closure the closing frames have no leaflets (nothing to calibrate\n"
      "against). --simulate-closure fills them by a fine simulation with the hidden parameters\n"
      "plus noise (--closure-set to change it); --quick uses a coarse model instead (20 x 10,\n"
      "one layer, dt 0.01 s), for trying the commands. A normal valve's marginal chordae are\n"
      "sized until its closure seals (13 closures on the patient's grid, about 40 s at 30 x 30;\n"
      "with --quick on 20 x 10) unless --no-tune-normal-chordae.");
  auto a = std::make_shared<PhantomArgs>();
  cmd->add_option("--seed", a->seed, "random seed (same seed, same patient)")->default_val(1);
  cmd->add_option("--out", a->out, "patient file to write (HDF5)")->required();
  cmd->add_option("--pathology", a->pathology,
                  "normal | prolapse_elongated_chordae | prolapse_ruptured_chordae | "
                  "functional_mr | stiff_leaflets (default: drawn)");
  add_grid_options(cmd, a->patient.ures, a->patient.vres);
  add_closing_anatomy_options(cmd, a->patient);
  cmd->add_flag("--force", a->force, "replace an existing file");
  cmd->add_flag("--simulate-closure", a->simulate_closure,
                "fill the closing frames by a fine simulation with the hidden parameters");
  cmd->add_flag("--quick", a->quick,
                "with --simulate-closure: a coarse model (20 x 10, one layer, dt 0.01 s); a "
                "normal valve's chordae are tuned on it too");
  add_tune_normal_option(cmd, a->tune_normal_chordae);
  cmd->add_option("--closure-set", a->closure_sets,
                  "name=value for that simulation (default: ures = vres = 40, 3 layers, "
                  "steps from 0.001 s at 0.05 mm error, linear systems to 1e-3)");
  cmd->add_option("--noise", a->noise_mm, "detection-like noise on the simulated surfaces, mm")
      ->default_val(0.5);
  run_on_parse(cmd, ctx, a, run_phantom);
}

}  // namespace mvtwin::tools
