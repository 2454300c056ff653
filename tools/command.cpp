// What every command shares (tools/command.h).
#include "command.h"

#include <chrono>
#include <cmath>
#include <iostream>
#include <utility>

#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/version.h"
#include "mvtwin/forward/chordae_tuning.h"
#include "progress.h"
#include "report.h"

namespace mvtwin::tools {
namespace fs = std::filesystem;

nlohmann::json provenance(const std::string& command_line) {
  return {
      {"mvtwin_version", kVersion}, {"command", command_line}, {"created_utc", utc_now_iso8601()}};
}

Patient read_patient_for_run(const fs::path& path, bool use_detected) {
  Patient p = read_patient(path, false);
  if (use_detected) {
    if (!p.detected)
      throw Error(path.string() + " has no detected sequence (run mvtwin detect first)");
    // Detection finds the leaflets, not the chordae: torn ones and their lengths stay the
    // patient's known anatomy.
    ValveSequence detected = *p.detected;
    detected.keep_chordae_anatomy(p.sequence);
    p.sequence = std::move(detected);
    p.provenance.source.append("; sequence detected from images (")
        .append(p.detected_by)
        .append(")");
  }
  print_assumed(p, std::cout);
  return p;
}

void refuse_overwrite(const fs::path& p, bool force) {
  if (fs::exists(p) && !force) {
    throw Error(p.string() + ": already exists (use --force to replace it)");
  }
}

void add_grid_options(CLI::App* cmd, int& ures, int& vres) {
  cmd->add_option("--ures", ures, "grid points around the annulus (even, >= 8)")->default_val(30);
  cmd->add_option("--vres", vres, "grid points from annulus to free edge (>= 3)")->default_val(30);
}

void add_closing_anatomy_options(CLI::App* cmd, VirtualPatientOptions& o) {
  cmd->add_flag("--taut-chordae,!--no-taut-chordae", o.taut_chordae_lengths,
                "record each marginal chorda's length, taut in the estimated closed valve (the "
                "default; --no-taut-chordae: rest lengths from end-diastole times group factors, "
                "the generator before the closing anatomy; docs/virtual-patients.md)");
  cmd->add_option("--commissure-clearance", o.commissure_clearance_mm,
                  "close the commissures at end-diastole until the folded surface is this far "
                  "from itself, mm (0: hanging vertically, as before the closing anatomy)")
      ->default_val(o.commissure_clearance_mm)
      ->check(CLI::Range(0.0, 10.0));
  cmd->add_flag("--myxomatous-flail,!--no-myxomatous-flail", o.myxomatous_flail,
                "a flail's valve is myxomatous: posterior leaflet modulus x 0.6, marginal chordae "
                "stiffness x 0.4 (the default since edition 3; docs/virtual-patients.md)");
  cmd->add_option("--tethering-scale", o.tethering_scale,
                  "functional MR's papillary displacement (apically 3-7 mm, apart 3-8 mm) times "
                  "this (1: edition 2)")
      ->default_val(o.tethering_scale)
      ->check(CLI::Range(0.0, 3.0));
}

void add_tune_normal_option(CLI::App* cmd, bool& tune) {
  cmd->add_flag("--tune-normal-chordae,!--no-tune-normal-chordae", tune,
                "size a normal valve's marginal chordae until its closure seals (the default: "
                "a healthy valve closes; 13 closures on the patient's grid, about 40 s at 30 x 30; "
                "docs/virtual-patients.md)");
}

NormalTuning tune_normal_if_asked(Patient* p, bool tune, int ures, int vres) {
  NormalTuning out;
  if (!tune || !forward::is_tunable_normal_valve(*p)) return out;
  forward::ChordaeTuningOptions o;
  o.simulation.model.ures = ures;
  o.simulation.model.vres = vres;
  const auto t0 = std::chrono::steady_clock::now();
  const forward::ChordaeTuning r = forward::tune_normal_virtual_patient(p, o);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.eroa_before_mm2 = r.eroa_mm2.front();
  out.eroa_mm2 = r.kept_eroa_mm2();
  if (std::isnan(out.eroa_mm2)) throw Error("tuning its chordae: " + r.failure);
  out.tuned = true;
  out.closures = static_cast<int>(r.eroa_mm2.size());
  out.kept = r.best;
  std::cout << (stderr_is_tty() ? "\n" : "") << p->id << " (normal): chordae tuned, EROA "
            << fixed(out.eroa_before_mm2, 1) << " -> " << fixed(out.eroa_mm2, 1) << " mm^2 at "
            << ures << " x " << vres << " (" << out.closures << " closures, "
            << fixed(out.seconds, 0) << " s)" << std::endl;
  return out;
}

}  // namespace mvtwin::tools
