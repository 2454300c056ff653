// mvtwin tune-chordae (tools/tune_chordae.h).
#include "tune_chordae.h"

#include <cmath>
#include <iostream>
#include <string>
#include <vector>

#include "exit_codes.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/forward/chordae_tuning.h"
#include "mvtwin/forward/closure_settings.h"
#include "report.h"

namespace mvtwin::tools {

int run_tune_chordae(const TuneChordaeArgs& a) {
  refuse_overwrite(a.out, a.force);
  Patient p = read_patient(a.file, false);
  forward::ChordaeTuningOptions o;
  o.iterations = a.iterations;
  o.shortest = a.shortest;
  o.gain = a.gain;
  o.reach_sites = a.reach_sites;
  o.longest = a.longest;
  for (const std::string& s : a.sets)
    forward::apply_option(s, &o.simulation,
                          "--set: tune-chordae simulates with the patient's hidden parameters");
  std::cout << "tuning the marginal chordae of " << p.id << " [SYNTHETIC]: " << o.iterations
            << " iterations at " << o.simulation.model.ures << " x " << o.simulation.model.vres
            << ", lengths within " << o.shortest << "-" << o.longest << " x their own" << std::endl;
  o.progress = [](int i, double eroa) {
    std::cout << "  closure " << i << ": EROA "
              << (std::isnan(eroa) ? std::string("failed") : fixed(eroa, 1) + " mm^2") << std::endl;
  };
  forward::ChordaeTuning t;
  try {
    t = forward::tune_normal_virtual_patient(&p, o);
  } catch (const Error& e) {
    throw Error(a.file + ": " + e.what());
  }
  if (!t.failure.empty()) std::cout << "  " << t.failure << "\n";
  if (std::isnan(t.kept_eroa_mm2())) {
    std::cerr << "mvtwin tune-chordae: the first closure failed; nothing written\n";
    return kExitFailed;
  }
  p.provenance.command += "  |  " + a.command_line;
  write_patient(a.out, p);
  std::cout << "wrote " << a.out << ": EROA " << fixed(t.eroa_mm2.front(), 1) << " -> "
            << fixed(t.kept_eroa_mm2(), 1) << " mm^2 at " << o.simulation.model.ures << " x "
            << o.simulation.model.vres << " (the lengths of closure " << t.best << "; SYNTHETIC)\n";
  return kExitOk;
}

void register_tune_chordae(CLI::App& app, Context& ctx) {
  auto* cmd = app.add_subcommand(
      "tune-chordae", "Size a normal virtual valve's marginal chordae so that it closes");
  cmd->footer(
      "Examples:\n"
      "  mvtwin tune-chordae normal.h5 --out tuned.h5   # long: 13 closures, about 40 s\n"
      "  mvtwin tune-chordae normal.h5 --out tuned_quick.h5 --iterations 1 --set ures=16 --set "
      "vres=8\n"
      "Each iteration simulates the closure with the patient's hidden parameters and, where the\n"
      "closed valve is open, lengthens or shortens the marginal chordae of the leaflet beside\n"
      "the opening (docs/virtual-patients.md, \"Chordae tuned to the simulated closure\"). The\n"
      "lengths of the closure with the smallest EROA are kept. A patient whose closing frames\n"
      "were simulated (phantom --simulate-closure) is refused: they were made with its old "
      "chordae.");
  auto a = std::make_shared<TuneChordaeArgs>();
  cmd->add_option("FILE", a->file, "virtual patient file (normal pathology)")->required();
  cmd->add_option("--out", a->out, "tuned patient file to write")->required();
  cmd->add_flag("--force", a->force, "replace an existing --out");
  cmd->add_option("--iterations", a->iterations, "length updates (iterations + 1 closures)")
      ->default_val(12)
      ->check(CLI::Range(0, 50));
  cmd->add_option("--shortest", a->shortest, "each chorda at least this times its own length")
      ->default_val(0.7)
      ->check(CLI::Range(0.3, 1.0));
  cmd->add_option("--gain", a->gain, "mm of length per mm of gap above the seal")
      ->default_val(1.0)
      ->check(CLI::Range(0.05, 10.0));
  cmd->add_option("--reach", a->reach_sites,
                  "chordae moved around an open column, insertion sites (of 28) to either side")
      ->default_val(2.5)
      ->check(CLI::Range(0.5, 14.0));
  cmd->add_option("--longest", a->longest, "each chorda at most this times its own length")
      ->default_val(1.3)
      ->check(CLI::Range(1.0, 5.0));
  cmd->add_option("--set", a->sets,
                  "name=value for the closures it simulates (default: the paper's grid)");
  run_on_parse(cmd, ctx, a, run_tune_chordae);
}

}  // namespace mvtwin::tools
