// mvtwin calibrate: fits chordae rest lengths, stiffnesses and pressure to a patient's observed
// closed valve (inverse/calibration.h).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <unistd.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "calibrate.h"
#include "exit_codes.h"
#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/calibration_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/version.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/forward/model_vtk.h"
#include "mvtwin/inverse/calibration.h"
#include "mvtwin/inverse/outcome_uncertainty.h"
#include "output_files.h"
#include "report.h"

namespace mvtwin::tools {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json nan_to_null(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

}  // namespace

json calibration_json(const CalibrationRecord& c) {
  const Eigen::VectorXd in_bounds = inverse::bounded_sd(c);
  json par = json::array();
  for (size_t i = 0; i < c.names.size(); ++i) {
    const auto k = static_cast<Eigen::Index>(i);
    par.push_back({{"name", c.names[i]},
                   {"unit", c.units[i]},
                   {"start", c.start[k]},
                   {"fitted", c.fitted[k]},
                   {"sd", nan_to_null(c.sd[k])},
                   {"sd_in_bounds", nan_to_null(in_bounds[k])},
                   {"truth", nan_to_null(c.truth[k])},
                   {"error", nan_to_null(c.fitted[k] - c.truth[k])},
                   {"identified", c.identified[i] != 0},
                   {"bounds", {c.lower[k], c.upper[k]}}});
  }
  json corr = json::array();
  for (Eigen::Index i = 0; i < c.correlation.rows(); ++i) {
    json row = json::array();
    for (Eigen::Index j = 0; j < c.correlation.cols(); ++j)
      row.push_back(nan_to_null(c.correlation(i, j)));
    corr.push_back(row);
  }
  json history = json::array();
  for (size_t h = 0; h < c.history_simulation.size(); ++h)
    history.push_back(
        {c.history_simulation[h], nan_to_null(c.history_error_mm[h]), c.history_best_mm[h]});
  json opts = json::object();
  for (const auto& [k, v] : c.options) opts[k] = v;
  return {{"patient_id", c.patient_id},
          {"synthetic", c.synthetic},
          {"method", c.method},
          {"termination", c.termination},
          {"parameters", par},
          {"correlation", corr},
          {"noise_mm", c.noise_mm},
          {"error_before_mm", c.error_before_mm},
          {"error_after_mm", c.error_after_mm},
          {"sims", c.simulations},
          {"failed_sims", c.failed_simulations},
          {"cache_hits", c.cache_hits},
          {"wall_s", c.wall_s},
          {"search_sims", c.search_simulations},
          {"search_error_before_mm", nan_to_null(c.search_error_before_mm)},
          {"search_error_after_mm", nan_to_null(c.search_error_after_mm)},
          {"refinement", c.refinement},
          {"history_columns", {"simulation", "error_mm", "best_mm"}},
          {"history", history},
          {"options", opts},
          {"provenance",
           {{"mvtwin_version", c.provenance.version},
            {"command", c.provenance.command},
            {"created_utc", c.provenance.created_utc},
            {"seed", c.provenance.seed},
            {"source", c.provenance.source}}}};
}

void add_fit_options(CLI::App* cmd, inverse::CalibrationOptions* co) {
  cmd->add_option("--jobs", co->jobs, "simulations at once")
      ->default_val(2)
      ->check(CLI::Range(1, 256));
  cmd->add_option(
         "--max-sims", co->max_simulations,
         "simulation budget (start, scan and optimizer; the uncertainty adds one per parameter)")
      ->default_val(co->max_simulations)
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--scan", co->restlength_scan,
                  "common rest-length offsets simulated before the optimizer starts")
      ->delimiter(',')
      ->default_str("-0.2,-0.1,0.1,0.2,0.3,0.4,0.5");
  cmd->add_option("--modulus-scan", co->modulus_scan,
                  "common multipliers of the leaflets' moduli simulated before the optimizer "
                  "starts (when the moduli are fitted)")
      ->delimiter(',')
      ->default_str("0.5,1.5,2,3,4");
  cmd->add_flag_callback(
      "--no-scan",
      [co] {
        co->restlength_scan.clear();
        co->modulus_scan.clear();
      },
      "start the optimizer at the defaults, without the scans");
}

int run_calibrate(const CalibrateArgs& a) {
  refuse_overwrite(a.out, a.force);
  refuse_overwrite(summary_path(a.out), a.force);
  const Patient p = read_patient_for_run(a.file, a.use_detected);
  forward::ClosureOptions o;
  ValveParameters start;  // the defaults: never the virtual patient's hidden values
  for (const std::string& s : a.sets) forward::apply_setting(s, &o, &start);
  inverse::ObjectiveOptions oo;
  oo.simulation = o;
  oo.all_closing_frames = a.all_frames;
  inverse::ClosureObjective objective(p, inverse::ParameterSpace(a.fit, start), oo);
  inverse::CalibrationOptions opt = a.calibration;
  if (!a.no_search_model) {
    opt.search_model = inverse::search_model_for(o);
    if (!a.search_sets.empty() && !opt.search_model) opt.search_model = o;
    for (const std::string& s : a.search_sets)
      forward::apply_option(s, &*opt.search_model,
                            "--search-set: the search model takes model options only");
  }
  std::cout << "calibrating " << p.id << (p.synthetic ? " [SYNTHETIC]" : "") << ": "
            << objective.space().names() << "\n  by "
            << inverse::fit_method_name(a.calibration.method) << ", " << a.calibration.jobs
            << " simulations at once, model " << o.model.ures << " x " << o.model.vres << ", dt "
            << o.dt << " s; " << objective.num_residuals() << " distances over "
            << objective.frames().size() << " frame(s)" << std::endl;
  const bool tty = isatty(fileno(stderr)) != 0;
  // One line per change of the simulation count or of the best error, with the time so far.
  struct Shown {
    int sims = -1;
    double best = -1;
  };
  auto shown = std::make_shared<Shown>();
  const auto t0 = std::chrono::steady_clock::now();
  opt.stage = [tty](const std::string& stage) {
    std::fprintf(stderr, "%s %s\n", tty ? "\n" : "", stage.c_str());
    std::fflush(stderr);
  };
  opt.progress = [tty, shown, t0](int it, double best, int sims) {
    if (sims == shown->sims && best == shown->best) return;
    shown->sims = sims;
    shown->best = best;
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::fprintf(stderr, "%s  iteration %d: best %.3f mm after %d simulations, %.1f s%s",
                 tty ? "\r" : "", it, best, sims, elapsed, tty ? "   " : "\n");
    std::fflush(stderr);
  };
  const inverse::CalibrationResult r = inverse::calibrate(objective, opt);
  if (tty) std::fprintf(stderr, "\n");
  CalibrationRecord rec = inverse::make_calibration_record(r, p, o, opt);
  rec.patient_file = a.file;
  rec.provenance.version = kVersion;
  rec.provenance.command = a.command_line;
  rec.provenance.created_utc = utc_now_iso8601();
  rec.provenance.source = assumed_note(p);
  write_calibration_file(a.out, rec);
  const fs::path js = summary_path(a.out);
  nlohmann::json summary = calibration_json(rec);
  print_calibration(rec, std::cout);
  if (a.use_detected) {
    // The model built from the detected anatomy, before and after, against the closing
    // surfaces stored in the file (for a virtual patient: its truth).
    const Patient stored = read_patient(a.file, false);
    if (stored.sequence.num_frames() == p.sequence.num_frames()) {
      Patient check = p;
      int compared = 0;
      for (int f = std::max(0, p.sequence.end_diastole + 1); f < p.sequence.num_frames(); ++f) {
        const auto i = static_cast<std::size_t>(f);
        check.sequence.frames[i].la_surface = stored.sequence.frames[i].la_surface;
        compared += stored.sequence.frames[i].la_surface ? 1 : 0;
      }
      if (compared > 0) {
        inverse::ClosureObjective against(check, objective.space(), oo);
        const inverse::Evaluation before = against.evaluate(r.start),
                                  after = against.evaluate(r.fitted);
        if (after.ok && before.ok) {
          std::printf("  against the stored valve%s: %.3f -> %.3f mm\n",
                      p.synthetic ? " (the virtual patient's truth)" : "", before.mean_mm,
                      after.mean_mm);
          summary["stored_valve_error_before_mm"] = before.mean_mm;
          summary["stored_valve_error_after_mm"] = after.mean_mm;
        }
      }
    }
  }
  write_json_file(js, summary);
  std::cout << "wrote " << a.out << " and " << js.string() << "\n";
  if (!a.vtk.empty()) {
    for (const auto& [name, x] : {std::pair{"before", r.start}, std::pair{"after", r.fitted}}) {
      const forward::ClosureResult s = objective.simulate(x);
      const auto files = forward::export_closure_vtk(s, fs::path(a.vtk) / name);
      std::cout << "wrote " << files.size() << " files to " << (fs::path(a.vtk) / name).string()
                << "\n";
    }
  }
  return kExitOk;
}

void register_calibrate(CLI::App& app, Context& ctx) {
  auto* cmd = app.add_subcommand("calibrate", "Fit chordae, stiffness and pressure to a patient");
  cmd->footer(
      "Examples:\n"
      "  mvtwin calibrate observed.h5 --fit restlength --set ures=20 --set vres=10 --max-sims 20 "
      "--out calib.h5\n"
      "  mvtwin calibrate observed.h5 --fit restlength,stiffness,pressure --method bobyqa --jobs 2 "
      "--out calib_full.h5   # long: the paper's grid\n"
      "Fits the chosen parameters (groups restlength, stiffness, pressure, modulus, or names)\n"
      "so that the simulated closed valve matches the observed one (symmetric point-to-mesh\n"
      "distance); the others stay at their defaults. Writes the calibration (HDF5), a JSON\n"
      "summary beside it, and with --vtk the valve simulated before and after.");
  auto a = std::make_shared<CalibrateArgs>();
  cmd->add_flag(
      "--use-detected", a->use_detected,
      "use the sequence detected from the images (mvtwin detect) instead of the stored one");
  cmd->add_option("FILE", a->file, "patient file with an observed closed valve")->required();
  cmd->add_option("--out", a->out, "calibration file (HDF5); a .json summary is written beside it")
      ->required();
  cmd->add_flag("--force", a->force, "replace an existing calibration file");
  cmd->add_option("--fit", a->fit, "what to fit")->default_val("restlength,stiffness,pressure");
  add_method_option(cmd, &a->calibration.method);
  cmd->add_option("--noise-mm", a->calibration.noise_mm,
                  "observation noise SD for the uncertainty, mm (default: the fit's residual RMS)");
  cmd->add_flag("--all-frames", a->all_frames,
                "compare every observed closing frame, not only the first closed one");
  add_fit_options(cmd, &a->calibration);
  cmd->add_option("--vtk", a->vtk, "directory for the valve before and after (ParaView)");
  cmd->add_option("--set", a->sets,
                  "name=value for the calibration model (repeatable), e.g. --set ures=20");
  auto* search_set = cmd->add_option(
      "--search-set", a->search_sets,
      "name=value for the model the optimizer searches with (repeatable; default: the "
      "calibration model at 0.8 of its grid, 24 x 24 at the paper's; the fit is then refined "
      "on the calibration model)");
  cmd->add_flag("--no-search-model", a->no_search_model,
                "search with the calibration model itself (slower at the paper's grid)")
      ->excludes(search_set);
  run_on_parse(cmd, ctx, a, run_calibrate);
}

CLI::Option* add_method_option(CLI::App* cmd, inverse::FitMethod* method) {
  std::string names;
  for (const auto& [name, m] : inverse::fit_methods_by_name())
    names += (names.empty() ? "" : " | ") + name;
  return cmd
      ->add_option_function<std::string>(
          "--method",
          [method](const std::string& name) { *method = *inverse::parse_fit_method(name); },
          "optimizer: " + names)
      ->check(CLI::Validator(
          [names](std::string& name) {
            return inverse::parse_fit_method(name)
                       ? std::string()
                       : "unknown method '" + name + "' (" + names + ")";
          },
          ""))
      ->type_name("METHOD")
      ->default_str(inverse::fit_method_name(*method));
}

}  // namespace mvtwin::tools
