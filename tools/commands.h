#pragma once
#include <filesystem>
#include <functional>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "mvtwin/core/patient.h"

namespace mvtwin::inverse {
struct CalibrationOptions;
enum class FitMethod;
}  // namespace mvtwin::inverse

namespace mvtwin::tools {

/// What the chosen subcommand will run, and the command line recorded in provenance.
struct Context {
  std::string command_line;
  std::function<int()> run;
};

/// What every JSON result of a command records about its making: mvtwin_version, command,
/// created_utc (add the seed, the source, ... where there is one).
nlohmann::json provenance(const Context& ctx);

void register_commands(CLI::App& app, Context& ctx);
/// mvtwin bench closure | solvers (tools/bench.cpp) and the bench commands below.
void register_bench(CLI::App& app, Context& ctx);
/// mvtwin calibrate (tools/calibrate.cpp).
void register_calibrate(CLI::App& app, Context& ctx);
/// The fit options of calibrate: --jobs, --max-sims, --scan, --no-scan.
void add_fit_options(CLI::App* cmd, inverse::CalibrationOptions* options);
/// --method METHOD (bobyqa | cobyla | neldermead | sbplx | ceres) into *method; an unknown name
/// is a usage error that lists the known ones.
CLI::Option* add_method_option(CLI::App* cmd, inverse::FitMethod* method);
/// mvtwin bench import (tools/bench_import.cpp), under the bench command.
void register_bench_import(CLI::App& bench, Context& ctx);
/// mvtwin clip (tools/clip.cpp).
void register_clip(CLI::App& app, Context& ctx);
/// mvtwin train-detector and mvtwin detect (tools/detect.cpp).
void register_detect(CLI::App& app, Context& ctx);
/// mvtwin import (tools/import.cpp).
void register_import(CLI::App& app, Context& ctx);
/// mvtwin study cohort | ... (tools/study.cpp).
void register_study(CLI::App& app, Context& ctx);
/// mvtwin render-tee (tools/render_tee.cpp).
void register_render_tee(CLI::App& app, Context& ctx);
/// Reads a patient file; with `use_detected` its detected sequence (mvtwin detect) replaces the
/// stored one for this run (the file is not changed). Throws mvtwin::Error when there is none.
Patient read_patient_for_run(const std::filesystem::path& path, bool use_detected);
/// Throws mvtwin::Error when `path` exists and `force` is not set.
void refuse_overwrite_path(const std::filesystem::path& path, bool force);

}  // namespace mvtwin::tools
