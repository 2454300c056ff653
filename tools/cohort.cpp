// mvtwin cohort (tools/cohort.h).
#include "cohort.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>

#include <nlohmann/json.hpp>

#include "exit_codes.h"
#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/forward/chordae_tuning.h"
#include "progress.h"

namespace mvtwin::tools {
namespace fs = std::filesystem;

int run_cohort(const CohortArgs& a) {
  std::error_code ec;
  fs::create_directories(a.out, ec);
  if (ec) throw Error(a.out + ": cannot create directory: " + ec.message());
  nlohmann::json manifest;
  manifest["format"] = "mvtwin-cohort";
  manifest["synthetic"] = true;
  manifest.update(provenance(a.command_line));
  manifest["seed"] = a.seed;
  manifest["n"] = a.n;
  manifest["taut_chordae_lengths"] = a.patient.taut_chordae_lengths;
  manifest["commissure_clearance_mm"] = a.patient.commissure_clearance_mm;
  manifest["myxomatous_flail"] = a.patient.myxomatous_flail;
  manifest["tethering_scale"] = a.patient.tethering_scale;
  manifest["tune_normal_chordae"] = a.tune_normal_chordae;
  if (a.tune_normal_chordae) manifest["chordae_tuning_edition"] = forward::kChordaeTuningEdition;
  manifest["patients"] = nlohmann::json::array();
  int made = 0, kept = 0, failed = 0;
  for (int i = 0; i < a.n; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "patient_%04d.h5", i);
    const fs::path path = fs::path(a.out) / name;
    const CohortMember member = cohort_member(a.seed, i);
    const std::uint64_t s = member.seed;
    // Normal valves are tuned to close when they have chordae lengths to tune.
    const bool tune = a.tune_normal_chordae && a.patient.taut_chordae_lengths &&
                      member.pathology == Pathology::kNormal;
    nlohmann::json entry{{"file", name}, {"seed", s}};
    try {
      bool reuse = false;
      if (fs::exists(path)) {
        try {
          const Patient old = read_patient(path, false);
          // Files of edition 2 and before do not record the severity options: theirs were off.
          const VirtualTruth none;
          const VirtualTruth& truth = old.truth ? *old.truth : none;
          const double clearance = truth.anatomy_or("commissure_clearance_ed_mm", 0.0);
          const double myxomatous = truth.anatomy_or("myxomatous_flail", 0.0);
          const double tethering = truth.anatomy_or("tethering_scale", 1.0);
          reuse =
              old.provenance.seed == s && old.sequence.ures == a.patient.ures &&
              old.sequence.vres == a.patient.vres &&
              old.sequence.marginal_chordae_lengths.empty() == !a.patient.taut_chordae_lengths &&
              clearance == a.patient.commissure_clearance_mm &&
              (myxomatous != 0.0) == a.patient.myxomatous_flail &&
              tethering == a.patient.tethering_scale &&
              forward::tuning_edition(old) == (tune ? forward::kChordaeTuningEdition : 0);
        } catch (const Error&) {
          reuse = false;  // damaged or foreign file: make it again
        }
      }
      Patient p;
      if (reuse) {
        p = read_patient(path, false);
        ++kept;
        entry["status"] = "kept";
      } else {
        VirtualPatientOptions o = a.patient;
        o.command = a.command_line + "  [patient " + std::to_string(i) + "]";
        p = make_cohort_patient(a.seed, i, o);
        // On the patient's own grid (the paper's 30 x 30 by default), its hidden parameters.
        const NormalTuning t = tune_normal_if_asked(&p, tune, a.patient.ures, a.patient.vres);
        if (t.tuned)
          entry["chordae_tuning"] = {{"eroa_before_mm2", t.eroa_before_mm2},
                                     {"eroa_mm2", t.eroa_mm2},
                                     {"closures", t.closures},
                                     {"kept_closure", t.kept},
                                     {"s", t.seconds}};
        write_patient(path, p);
        ++made;
        entry["status"] = "made";
      }
      entry["id"] = p.id;
      entry["pathology"] = std::string(pathology_name(p.truth->pathology));
    } catch (const Error& e) {
      ++failed;
      entry["status"] = "failed";
      entry["error"] = e.what();
      std::cerr << (stderr_is_tty() ? "\n" : "") << "mvtwin cohort: patient " << i
                << " failed: " << e.what() << "\n";
    }
    manifest["patients"].push_back(entry);
    count_line("[cohort] " + std::to_string(i + 1) + "/" + std::to_string(a.n) + " (made " +
                   std::to_string(made) + ", kept " + std::to_string(kept) + ", failed " +
                   std::to_string(failed) + ")",
               i + 1 == a.n);
  }
  manifest["made"] = made;
  manifest["kept"] = kept;
  manifest["failed"] = failed;
  const fs::path mpath = fs::path(a.out) / "cohort.json";
  write_atomically(mpath, [&](const fs::path& tmp) {
    std::ofstream f(tmp);
    f << manifest.dump(2) << "\n";
    if (!f) throw Error(mpath.string() + ": write failed");
  });
  std::cout << "cohort of " << a.n << " virtual patients in " << a.out << " (made " << made
            << ", kept " << kept << ", failed " << failed << "); manifest " << mpath.string()
            << "\n";
  return failed ? int{kExitFailed} : int{kExitOk};
}

void register_cohort(CLI::App& app, Context& ctx) {
  auto* cmd = app.add_subcommand("cohort", "Make many virtual patients (resumable)");
  cmd->footer(
      "Examples:\n"
      "  mvtwin cohort --n 5 --seed 2026 --out cohort/   # long: the normal valve's chordae tuned\n"
      "  mvtwin cohort --n 5 --seed 2026 --ures 16 --vres 8 --out coarse_cohort/\n"
      "Patient i has the seed and pathology every command gives it (the pathologies in turn),\n"
      "so mvtwin study cohort --seed 2026 draws the same patients.\n"
      "Normal valves have their marginal chordae tuned until their closure seals (as mvtwin\n"
      "tune-chordae, on the cohort's grid: about 40 s each at 30 x 30; --no-tune-normal-chordae\n"
      "keeps the generator's lengths). A healthy valve closes without a regurgitant orifice.\n"
      "Existing valid patient files are kept (the run resumes); a patient that fails is\n"
      "reported in cohort.json and the others go on.");
  auto a = std::make_shared<CohortArgs>();
  cmd->add_option("--n", a->n, "number of patients")->default_val(25)->check(CLI::Range(1, 100000));
  cmd->add_option("--seed", a->seed, "cohort seed")->default_val(1);
  cmd->add_option("--out", a->out, "output directory")->required();
  add_grid_options(cmd, a->patient.ures, a->patient.vres);
  add_closing_anatomy_options(cmd, a->patient);
  add_tune_normal_option(cmd, a->tune_normal_chordae);
  run_on_parse(cmd, ctx, a, run_cohort);
}

}  // namespace mvtwin::tools
