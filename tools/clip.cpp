// mvtwin clip: predicts the closure after an edge-to-edge clip (inverse/clip_prediction.h).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "clip.h"
#include "exit_codes.h"
#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/calibration_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/simulation_file.h"
#include "mvtwin/core/version.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/forward/model_vtk.h"
#include "mvtwin/inverse/clip_prediction.h"
#include "output_files.h"
#include "progress.h"
#include "report.h"

namespace mvtwin::tools {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string f1(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f", v);
  return b;
}

std::string describe(const std::vector<inverse::ClipSite>& sites) {
  std::string s;
  for (const auto& c : sites) {
    char b[64];
    std::snprintf(b, sizeof b, "%s%.2f,%.2f", s.empty() ? "" : ";", c.position, c.depth);
    s += b;
  }
  return s.empty() ? "none" : s;
}

json quality_json(const inverse::ClosureQuality& q) {
  json j = {{"converged", q.converged}, {"reason", q.reason}, {"clip_gap_end_mm", q.clip_gap_mm}};
  if (q.converged) j.update(orifice_json(q.orifice));
  return j;
}

std::string quality_line(const inverse::ClosureQuality& q) {
  if (!q.converged) return "simulation failed: " + q.reason;
  return orifice_line(q.orifice);
}

/// The simulation options a calibration used (its options record), else the defaults.
forward::ClosureOptions options_of(const CalibrationRecord& c) {
  forward::ClosureOptions o;
  for (const auto& [k, v] : c.options) {
    if (k.rfind("fit_", 0) == 0 || k == "clips" || k == "ruptured_marginal_chordae" ||
        k == "record_every")
      continue;
    forward::apply_option(k + "=" + v, &o);
  }
  return o;
}

}  // namespace

int run_clip(const ClipArgs& a) {
  if (a.at.empty() == !a.suggest) throw Error("clip: give either --at SITES or --suggest");
  const Patient p = read_patient_for_run(a.file, a.use_detected);
  ValveParameters par;
  forward::ClosureOptions o;
  std::string source = "default parameters (uncalibrated)";
  if (!a.params.empty()) {
    const CalibrationRecord c = read_calibration_file(a.params);
    if (c.patient_id != p.id) {
      throw Error(a.params + " calibrates '" + c.patient_id + "', not '" + p.id + "'");
    }
    par = c.parameters;
    o = options_of(c);
    source = "calibrated parameters from " + a.params;
  }
  if (a.true_params) {
    if (!p.synthetic || !p.truth)
      throw Error(a.file +
                  ": --true-params needs a virtual patient (it holds no hidden parameters)");
    par = p.truth->parameters;
    source = "the virtual patient's hidden (true) parameters";
  }
  for (const std::string& s_ : a.sets) forward::apply_setting(s_, &o, &par);
  if (!a.out.empty()) {
    refuse_overwrite(a.out, a.force);
    refuse_overwrite(fs::path(a.out).replace_extension(".json"), a.force);
  }
  std::cout << "clip prediction for " << p.id << (p.synthetic ? " [SYNTHETIC]" : "") << " with "
            << source << std::endl;
  std::vector<std::vector<inverse::ClipSite>> cands{{}};  // first: no clip
  if (a.suggest) {
    for (auto& c : inverse::clip_candidates(a.pairs)) cands.push_back(c);
  } else {
    cands.push_back(inverse::parse_clip_sites(a.at));
  }
  std::cout << "  simulating " << cands.size() << " closures (" << a.jobs << " at once) ..."
            << std::endl;
  std::vector<inverse::ClipScenario> res = inverse::simulate_clips(p, par, o, cands, a.jobs);
  const inverse::ClipScenario before = res.front();
  std::cout << "before: " << quality_line(before.quality) << "\n";
  json j{{"patient_id", p.id},
         {"synthetic", p.synthetic},
         {"parameters_from", source},
         {"options", forward::describe_options(o)},
         {"before", quality_json(before.quality)},
         {"provenance", provenance(a.command_line)}};
  j["provenance"]["seed"] = p.provenance.seed;
  j["provenance"]["source"] = assumed_note(p);
  std::vector<inverse::ClipScenario> clipped(res.begin() + 1, res.end());
  if (a.suggest) {
    inverse::rank_by_residual_orifice(&clipped);
    std::cout << "candidates ranked by residual orifice:\n";
    json ranked = json::array();
    int rank = 0;
    for (const auto& s : clipped) {
      std::cout << "  " << ++rank << ". clip at " << describe(s.sites) << ": "
                << quality_line(s.quality) << "\n";
      ranked.push_back({{"sites", describe(s.sites)}, {"after", quality_json(s.quality)}});
    }
    j["ranked"] = ranked;
  } else {
    const auto& s = clipped.front();
    std::cout << "after clip at " << describe(s.sites) << ": " << quality_line(s.quality) << "\n";
    for (size_t c = 0; c < s.quality.clip_gap_mm.size(); ++c)
      std::cout << "  clip " << c + 1 << ": atrial surfaces " << f1(s.quality.clip_gap_mm[c])
                << " mm apart at the end\n";
    j["sites"] = describe(s.sites);
    j["after"] = quality_json(s.quality);
  }
  // The chosen (or best) scenario as a full simulation file and VTK.
  if (!a.out.empty() || !a.vtk.empty()) {
    const auto& best = clipped.front();
    forward::ClosureOptions oc = o;
    for (const auto& s : best.sites) oc.clips.push_back(inverse::clip_options(s));
    oc.record_every = std::max(1, static_cast<int>(0.1 / oc.dt));
    oc.progress = progress_line("  clipped closure");
    const forward::ClosureResult r = forward::simulate_closure(p.sequence, par, oc);
    if (!a.out.empty()) {
      write_simulation_result(a.out, r, oc, par, p, a.file, a.command_line);
      const fs::path js = fs::path(a.out).replace_extension(".json");
      write_json_file(js, j);
      std::cout << "wrote " << a.out << " and " << js.string() << "\n";
    }
    if (!a.vtk.empty()) {
      const auto files = forward::export_closure_vtk(r, a.vtk);
      std::cout << "wrote " << files.size() << " files to " << a.vtk << "\n";
    }
  }
  for (const auto& s : clipped)
    if (s.quality.converged) return kExitOk;
  return static_cast<int>(kExitFailed);
}

void register_clip(CLI::App& app, Context& ctx) {
  auto* cmd = app.add_subcommand("clip", "Predict the closure after an edge-to-edge clip");
  cmd->footer(
      "Examples:\n  mvtwin clip observed.h5 --params calib.h5 --at 0.5,1 --out clipped.h5\n"
      "  mvtwin clip observed.h5 --params calib.h5 --at \"0.35,1;0.65,1\" --out two_clips.h5\n"
      "  mvtwin clip observed.h5 --params calib.h5 --suggest --pairs --jobs 2\n"
      "A site is position,depth: position along the coaptation line (0 = anterolateral\n"
      "commissure, 1 = posteromedial), depth 1 = the free edges. The open valve is clipped with\n"
      "the pressure off and the boundary held, then closes under the patient's motion and\n"
      "pressure with the calibrated parameters (--params; the defaults without it). Reports\n"
      "the regurgitant orifice, its openings and the coaptation length before and after.");
  auto a = std::make_shared<ClipArgs>();
  cmd->add_flag(
      "--use-detected", a->use_detected,
      "use the sequence detected from the images (mvtwin detect) instead of the stored one");
  cmd->add_option("FILE", a->file, "patient file (the pre-operative anatomy)")->required();
  auto* params_opt = cmd->add_option("--params", a->params, "calibration file (mvtwin calibrate)");
  cmd->add_flag(
         "--true-params", a->true_params,
         "a virtual patient's hidden parameters (synthetic only: what a calibration's error costs)")
      ->excludes(params_opt);
  cmd->add_option("--at", a->at, "clip site(s): position,depth[;position,depth]");
  cmd->add_option("--out", a->out,
                  "result of the clipped closure (simulation file; a .json "
                  "summary is written beside it)");
  cmd->add_option("--vtk", a->vtk, "directory for the clipped closure (ParaView)");
  cmd->add_flag("--suggest", a->suggest, "search sites along the coaptation line and rank them");
  cmd->add_flag("--pairs", a->pairs, "with --suggest: also pairs of clips");
  cmd->add_option("--jobs", a->jobs, "simulations at once")
      ->default_val(2)
      ->check(CLI::Range(1, 256));
  cmd->add_flag("--force", a->force, "replace existing output files");
  cmd->add_option("--set", a->sets, "name=value for the simulation (repeatable)");
  run_on_parse(cmd, ctx, a, run_clip);
}

}  // namespace mvtwin::tools
