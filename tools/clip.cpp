// mvtwin clip: predicts the closure after an edge-to-edge clip (inverse/clip_prediction.h).
#include <chrono>
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
#include "clip_report.h"
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

json quality_json(const inverse::ClosureQuality& q) {
  json j = {{"converged", q.converged}, {"reason", q.reason}, {"clip_gap_end_mm", q.clip_gap_mm}};
  if (q.converged) j.update(orifice_json(q.orifice));
  json grasps = json::array();
  for (const forward::ClipGrasp& g : q.clip_grasps) {
    grasps.push_back({{"device", g.device},
                      {"anterior_insertion_mm", g.anterior_insertion_mm},
                      {"posterior_insertion_mm", g.posterior_insertion_mm},
                      {"anterior_nodes", g.anterior_nodes},
                      {"posterior_nodes", g.posterior_nodes},
                      {"line_begin", g.line_begin},
                      {"line_end", g.line_end}});
  }
  j["grasps"] = grasps;
  const inverse::ClipFlags f = inverse::clip_flags(q.clip_grasps);
  j["detachment_risk"] = f.detachment_risk;
  j["min_insertion_mm"] = f.min_insertion_mm;
  return j;
}

std::string quality_line(const inverse::ClosureQuality& q) {
  if (!q.converged) return "simulation failed: " + q.reason;
  std::string s = orifice_line(q.orifice);
  const inverse::ClipFlags f = inverse::clip_flags(q.clip_grasps);
  if (!q.clip_grasps.empty() && f.min_insertion_mm > 0)
    s += "; shallowest leaflet insertion " + f1(f.min_insertion_mm) + " mm" +
         (f.detachment_risk ? " (DETACHMENT RISK)" : "");
  return s;
}

json opening_json(const inverse::ClipOpening& o) {
  if (!o.computed) return json(nullptr);
  if (!o.converged) return {{"converged", false}, {"reason", o.reason}};
  return {{"converged", true},
          {"mva_cm2", o.mva_cm2},
          {"openings_cm2", o.openings_cm2},
          {"gradient_mmhg", o.gradient_mmhg},
          {"stenosis", o.stenosis},
          {"frame", o.frame},
          {"fallback", o.fallback}};
}

std::string opening_line(const inverse::ClipOpening& o) {
  if (!o.computed) return "";
  if (!o.converged) return "; diastole failed: " + o.reason;
  char b[64];
  std::snprintf(b, sizeof b, "MVA %.2f cm^2", o.mva_cm2);
  return std::string("; open: ") + b + " (" + std::to_string(o.openings_cm2.size()) + " opening" +
         (o.openings_cm2.size() == 1 ? "" : "s") + "), mean gradient " + f1(o.gradient_mmhg) +
         " mmHg" + (o.stenosis ? " (STENOSIS)" : "") +
         (o.fallback.empty() ? ""
                             : " [on the end-diastolic frame: the grasp on the widest failed]");
}

json loads_json(const inverse::GraspLoads& g) {
  return {{"peak_stress_kpa", g.stress_p95_after_kpa},
          {"peak_stress_before_kpa", g.stress_p95_before_kpa},
          {"max_stress_kpa", g.stress_max_after_kpa},
          {"marginal_chorda_tension_n", g.marginal_tension_after_n},
          {"marginal_chorda_tension_before_n", g.marginal_tension_before_n}};
}

std::string loads_line(const inverse::GraspLoads& g) {
  return "; stress near the grasp " + f1(g.stress_p95_before_kpa) + " -> " +
         f1(g.stress_p95_after_kpa) + " kPa (95th percentile), largest marginal chorda " +
         f1(g.marginal_tension_before_n) + " -> " + f1(g.marginal_tension_after_n) + " N";
}

/// "EROA 4.8 mm^2 (95 %: 2.1-7.5)"-style intervals of a scenario's outcomes, and their SDs as
/// NAME_sd in JSON.
std::string interval_line(const inverse::ClipScenario& s, const inverse::ClosureQuality& before) {
  const inverse::ClipUncertainty& u = s.uncertainty;
  if (!u.computed) return "";
  const Eigen::VectorXd v = inverse::clip_outcomes(s, before);
  const char* label[] = {"EROA", "MVA", "gradient", "stress"};
  const char* unit[] = {"mm^2", "cm^2", "mmHg", "kPa"};
  std::string out = "; 95 % intervals from the calibration:";
  bool any = false;
  for (int k = 0; k < inverse::kClipOutcomes; ++k) {
    if (!std::isfinite(v[k])) continue;
    if (k == 3 && s.sites.empty()) continue;
    char b[96];
    if (std::isfinite(u.sd[k])) {
      const double h = inverse::kZ95 * u.sd[k];
      std::snprintf(b, sizeof b, " %s %.*f-%.*f %s", label[k], k == 1 ? 2 : 1,
                    std::max(0.0, v[k] - h), k == 1 ? 2 : 1, v[k] + h, unit[k]);
    } else {
      std::snprintf(b, sizeof b, " %s ? (a simulation failed)", label[k]);
    }
    out += (any ? "," : "") + std::string(b);
    any = true;
  }
  return any ? out : "";
}

void add_sd_json(const inverse::ClipScenario& s, json* j) {
  const inverse::ClipUncertainty& u = s.uncertainty;
  if (!u.computed) return;
  for (int k = 0; k < inverse::kClipOutcomes; ++k) {
    const double sd = u.sd[k];
    (*j)[std::string(inverse::kClipOutcomeNames[k]) + "_sd"] =
        std::isfinite(sd) ? json(sd) : json(nullptr);
  }
  (*j)["interval_failed_simulations"] = u.failed;
}

json sites_json(const std::vector<inverse::ClipSite>& sites) {
  json positions = json::array();
  for (const auto& s : sites) positions.push_back(s.position);
  return {{"device", sites.empty() ? std::string("none") : sites.front().device},
          {"positions", positions},
          {"sites", inverse::describe_sites(sites)}};
}

json everest_json(const inverse::EverestCriteria& e) {
  auto n = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
  return {{"coaptation_length_mm", n(e.coaptation_length_mm)},
          {"coaptation_length_ok", e.coaptation_length_ok},
          {"coaptation_depth_mm", n(e.coaptation_depth_mm)},
          {"coaptation_depth_ok", e.coaptation_depth_ok},
          {"flail_gap_mm", n(e.flail_gap_mm)},
          {"flail_gap_ok", e.flail_gap_ok},
          {"flail_width_mm", n(e.flail_width_mm)},
          {"flail_width_ok", e.flail_width_ok},
          {"all_ok", e.all_ok()}};
}

std::string everest_line(const inverse::EverestCriteria& e) {
  auto mark = [](bool ok) { return ok ? std::string("ok") : std::string("NOT MET"); };
  return "EVEREST anatomy: coaptation length " + f1(e.coaptation_length_mm) +
         " mm (>= 2: " + mark(e.coaptation_length_ok) + "), depth " + f1(e.coaptation_depth_mm) +
         " mm (< 11: " + mark(e.coaptation_depth_ok) + "), largest gap " + f1(e.flail_gap_mm) +
         " mm (flail gap < 10: " + mark(e.flail_gap_ok) + "), its width " + f1(e.flail_width_mm) +
         " mm (flail width < 15: " + mark(e.flail_width_ok) + ")";
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
  const auto started = std::chrono::steady_clock::now();
  const Patient p = read_patient_for_run(a.file, a.use_detected);
  ValveParameters par;
  forward::ClosureOptions o;
  std::string source = "default parameters (uncalibrated)";
  inverse::CalibrationPosterior posterior;
  posterior.why_not = "no calibration (--params)";
  if (!a.params.empty()) {
    const CalibrationRecord c = read_calibration_file(a.params);
    if (c.patient_id != p.id) {
      throw Error(a.params + " calibrates '" + c.patient_id + "', not '" + p.id + "'");
    }
    par = c.parameters;
    o = options_of(c);
    source = "calibrated parameters from " + a.params;
    posterior = inverse::posterior_of(c);
  }
  if (a.true_params) {
    if (!p.synthetic || !p.truth)
      throw Error(a.file +
                  ": --true-params needs a virtual patient (it holds no hidden parameters)");
    par = p.truth->parameters;
    source = "the virtual patient's hidden (true) parameters";
    posterior.why_not = "the hidden parameters are exact";
  }
  for (const std::string& s_ : a.sets) forward::apply_setting(s_, &o, &par);
  if (!a.sets.empty() && posterior.usable) {
    // A --set may change a fitted parameter: the posterior's base follows the settings.
    forward::ClosureOptions unused;
    for (const std::string& s_ : a.sets) forward::apply_setting(s_, &unused, &posterior.base);
  }
  const bool intervals = posterior.usable && !a.no_intervals;
  if (a.no_intervals) posterior.why_not = "--no-intervals";
  if (!a.out.empty()) {
    refuse_overwrite(a.out, a.force);
    refuse_overwrite(summary_path(a.out), a.force);
  }
  std::cout << "clip prediction for " << p.id << (p.synthetic ? " [SYNTHETIC]" : "") << " with "
            << source << std::endl;
  std::vector<std::vector<inverse::ClipSite>> cands{{}};  // first: no clip
  std::vector<std::string> devices = a.devices;
  if (devices.empty()) {
    for (const forward::ClipDevice& d : forward::clip_devices()) devices.push_back(d.name);
  }
  if (a.suggest) {
    for (auto& c : inverse::clip_candidates(false, devices)) cands.push_back(c);
  } else {
    cands.push_back(inverse::parse_clip_sites(a.at, a.device));
  }
  std::cout << "  simulating " << cands.size() << " closures (" << a.jobs << " at once) ..."
            << std::endl;
  std::vector<inverse::ClipScenario> res = inverse::simulate_clips(p, par, o, cands, a.jobs);
  // The valve opened in diastole: without a clip, and (below) the chosen or best options.
  const forward::DiastoleOptions diastole;
  inverse::open_clips(p, par, o, diastole, 1, a.jobs, &res);
  const inverse::ClipScenario before = res.front();
  std::cout << "before: " << quality_line(before.quality) << opening_line(before.opening) << "\n";
  const inverse::EverestCriteria everest = inverse::everest_criteria(before.quality.orifice);
  if (before.quality.converged) std::cout << everest_line(everest) << "\n";
  json j{{"patient_id", p.id},
         {"synthetic", p.synthetic},
         {"parameters_from", source},
         {"options", forward::describe_options(o)},
         {"before", quality_json(before.quality)},
         {"before_open", opening_json(before.opening)},
         {"everest", everest_json(everest)},
         {"diastole",
          {{"transmitral_mmhg", diastole.transmitral_mmhg},
           {"stroke_volume_ml", diastole.stroke_volume_ml},
           {"filling_time_s", diastole.filling_time_s},
           {"gradient", "Gorlin, mitral constant 37.7"}}},
         {"provenance", provenance(a.command_line)}};
  j["intervals"] = {{"computed", intervals},
                    {"why_not", intervals ? "" : posterior.why_not},
                    {"method",
                     "linearized: one simulation one SD along each direction of the "
                     "calibration's covariance combined with the parameters' bounds as a prior "
                     "(each range's uniform variance; a parameter the data do not determine, "
                     "listed in unidentified_parameters, gets its range's spread), retried half "
                     "as far where a simulation fails; and the mesh's part: the change on a mesh "
                     "4/3 finer at the fitted values; NAME_sd = sqrt(both squared) per outcome, "
                     "95 % = 1.96 SD"},
                    {"unidentified_parameters", posterior.unidentified}};
  j["provenance"]["seed"] = p.provenance.seed;
  j["provenance"]["source"] = assumed_note(p);
  std::vector<inverse::ClipScenario> clipped(res.begin() + 1, res.end());
  inverse::SigmaPoints sp;
  if (a.suggest) {
    inverse::rank_by_residual_orifice(&clipped);
    if (a.pairs) {
      // Pairs around the three best single clips (their device, a second clip at least 0.2
      // away along the line).
      std::vector<std::vector<inverse::ClipSite>> best;
      for (size_t i = 0; i < std::min<size_t>(3, clipped.size()); ++i)
        if (clipped[i].quality.converged) best.push_back(clipped[i].sites);
      const auto pairs = inverse::pairs_around(best);
      std::cout << "  simulating " << pairs.size() << " pairs around the best single clips ..."
                << std::endl;
      for (auto& sc : inverse::simulate_clips(p, par, o, pairs, a.jobs)) clipped.push_back(sc);
      inverse::rank_by_residual_orifice(&clipped);
    }
    // The best options opened in diastole (stenosis decides whether a clip may be placed).
    inverse::open_clips(p, par, o, diastole, static_cast<size_t>(a.open_best), a.jobs, &clipped);
    if (intervals) {
      std::cout << "  intervals: the best " << a.open_best
                << " options and the valve without a clip at each sigma point of the "
                   "calibration ..."
                << std::endl;
      const size_t n = std::min(static_cast<size_t>(a.open_best), clipped.size());
      std::vector<inverse::ClipScenario> all{before};
      all.insert(all.end(), clipped.begin(), clipped.begin() + static_cast<std::ptrdiff_t>(n));
      sp = inverse::propagate_clip_uncertainty(p, posterior, o, diastole, before.quality, n + 1,
                                               a.jobs, &all);
      for (size_t i = 0; i < n; ++i) clipped[i].uncertainty = all[i + 1].uncertainty;
      res.front().uncertainty = all.front().uncertainty;
      std::cout << "before: " << interval_line(all.front(), before.quality).substr(2) << "\n";
      add_sd_json(all.front(), &j["before"]);
    }
    std::cout << "options ranked by the effective regurgitant orifice left (the best "
              << a.open_best << " also opened in diastole):\n";
    json ranked = json::array();
    int rank = 0;
    for (const auto& s : clipped) {
      const inverse::GraspLoads loads = inverse::grasp_loads(before.quality, s.quality);
      const bool tied = rank > 0 && inverse::indistinguishable(sp, clipped.front(), s);
      std::cout << "  " << ++rank << ". " << inverse::describe_sites(s.sites) << ": "
                << quality_line(s.quality) << opening_line(s.opening)
                << (s.quality.converged ? loads_line(loads) : "")
                << interval_line(s, before.quality)
                << (tied ? " [cannot be told from option 1]" : "") << "\n";
      json r = sites_json(s.sites);
      add_sd_json(s, &r);
      if (s.uncertainty.computed) r["indistinguishable_from_best"] = rank == 1 || tied;
      r["after"] = quality_json(s.quality);
      r["open"] = opening_json(s.opening);
      if (s.quality.converged) r.update(loads_json(loads));
      ranked.push_back(r);
    }
    j["ranked"] = ranked;
  } else {
    inverse::open_clips(p, par, o, diastole, 1, a.jobs, &clipped);
    if (intervals) {
      std::cout << "  intervals: the clipped valve and the valve without a clip at each sigma "
                   "point of the calibration ..."
                << std::endl;
      std::vector<inverse::ClipScenario> both{res.front(), clipped.front()};
      sp = inverse::propagate_clip_uncertainty(p, posterior, o, diastole, before.quality, 2, a.jobs,
                                               &both);
      clipped.front().uncertainty = both[1].uncertainty;
      res.front().uncertainty = both[0].uncertainty;
      std::cout << "before: " << interval_line(both[0], before.quality).substr(2) << "\n";
      add_sd_json(both[0], &j["before"]);
    }
    const auto& s = clipped.front();
    const inverse::GraspLoads loads = inverse::grasp_loads(before.quality, s.quality);
    std::cout << "after " << inverse::describe_sites(s.sites) << ": " << quality_line(s.quality)
              << opening_line(s.opening) << (s.quality.converged ? loads_line(loads) : "")
              << interval_line(s, before.quality) << "\n";
    for (size_t c = 0; c < s.quality.clip_gap_mm.size(); ++c)
      std::cout << "  clip " << c + 1 << ": grasped leaflets " << f1(s.quality.clip_gap_mm[c])
                << " mm apart at the end (atrial surfaces)\n";
    j.update(sites_json(s.sites));
    j["after"] = quality_json(s.quality);
    if (s.quality.converged) j.update(orifice_json(s.quality.orifice));
    const inverse::ClipFlags f = inverse::clip_flags(s.quality.clip_grasps);
    j["detachment_risk"] = f.detachment_risk;
    j["open"] = opening_json(s.opening);
    if (s.quality.converged) j.update(loads_json(loads));
    add_sd_json(s, &j);
    if (s.opening.converged) {
      j["mva_cm2"] = s.opening.mva_cm2;
      j["gradient_mmhg"] = s.opening.gradient_mmhg;
      j["stenosis"] = s.opening.stenosis;
    }
  }
  if (!a.report.empty()) {
    ClipPlan plan;
    plan.patient = &p;
    plan.parameters_from = source;
    plan.before = res.front();
    plan.everest = everest;
    plan.ranked = clipped;
    plan.sigma = sp;
    plan.intervals_why_not = posterior.why_not;
    plan.command_line = a.command_line;
    plan.jobs = a.jobs;
    plan.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    write_clip_report(a.report, plan);
    std::cout << "wrote the clip plan's report to " << (fs::path(a.report) / "report.html").string()
              << " (and report.md)\n";
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
      const fs::path js = summary_path(a.out);
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
      "Examples:\n  mvtwin clip observed.h5 --params calib.h5 --at 0.5 --out clipped.h5\n"
      "  mvtwin clip observed.h5 --params calib.h5 --device NTW --at \"0.35;0.65\" --no-intervals "
      "--out two.h5\n"
      "  mvtwin clip observed.h5 --params calib.h5 --suggest --devices XTW --open-best 1 "
      "--report plan/\n"
      "  mvtwin clip observed.h5 --params calib.h5 --suggest --pairs --jobs 2   # long: 6 devices\n"
      "  mvtwin clip observed.h5 --params calib.h5 --device spring --at 0.5,1 --no-intervals   "
      "# the paper's clip\n"
      "A site is a position along the coaptation line (0 = anterolateral commissure, 1 =\n"
      "posteromedial). The device (--device, default XTW; docs/clip-devices.md) grasps a band\n"
      "of each leaflet as wide as its arms and as deep as the leaflet inserts (from the\n"
      "geometry, capped by the arm) on the open valve with the pressure off and the boundary\n"
      "held, then the valve closes under the patient's motion and pressure with the calibrated\n"
      "parameters (--params; the defaults without it). Reports the regurgitant orifice (EROA,\n"
      "MR grade, openings), coaptation, the leaflet insertions (detachment risk below 4 mm) and\n"
      "the EVEREST anatomic criteria. --suggest ranks every device at positions 0.2-0.8;\n"
      "--pairs adds pairs around the three best. With a calibration that has a covariance,\n"
      "every outcome comes with a 95 % interval: the calibration's spread and the change on a\n"
      "mesh 4/3 finer (--no-intervals skips them); --report DIR\n"
      "writes the plan as report.md/.html with pictures (docs/clip-devices.md).");
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
  cmd->add_option("--at", a->at, "clip site(s): position[;position] along the coaptation line");
  cmd->add_option("--device", a->device,
                  "the device at --at: NT, XT, NTW, XTW (MitraClip G4), ACE, P10 (PASCAL), or "
                  "spring (the paper's clip: a spring at position,depth)")
      ->default_val(a->device);
  cmd->add_option("--devices", a->devices,
                  "with --suggest: the devices to search (default: every device of the table)");
  cmd->add_option("--out", a->out,
                  "result of the clipped closure (simulation file; a .json "
                  "summary is written beside it)");
  cmd->add_option("--vtk", a->vtk, "directory for the clipped closure (ParaView)");
  cmd->add_option("--report", a->report,
                  "folder for the clip plan's report (report.md, report.html, en-face PNGs)");
  cmd->add_flag("--suggest", a->suggest, "search sites along the coaptation line and rank them");
  cmd->add_flag("--pairs", a->pairs, "with --suggest: also pairs of clips");
  cmd->add_option("--open-best", a->open_best,
                  "with --suggest: how many of the best options to open in diastole (MVA)")
      ->default_val(a->open_best)
      ->check(CLI::Range(0, 1000));
  cmd->add_flag("--no-intervals", a->no_intervals,
                "skip the intervals from the calibration's covariance and the mesh (one more "
                "simulation per fitted direction and option, and one on the finer mesh)");
  cmd->add_option("--jobs", a->jobs, "simulations at once")
      ->default_val(2)
      ->check(CLI::Range(1, 256));
  cmd->add_flag("--force", a->force, "replace existing output files");
  cmd->add_option("--set", a->sets, "name=value for the simulation (repeatable)");
  run_on_parse(cmd, ctx, a, run_clip);
}

}  // namespace mvtwin::tools
