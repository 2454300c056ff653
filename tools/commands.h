#pragma once
#include <filesystem>
#include <functional>
#include <string>

#include <CLI/CLI.hpp>

namespace mvtwin::tools {

/// What the chosen subcommand will run, and the command line recorded in provenance.
struct Context {
  std::string command_line;
  std::function<int()> run;
};

void register_commands(CLI::App& app, Context& ctx);
/// mvtwin bench closure | accuracy | stability (tools/bench.cpp).
void register_bench(CLI::App& app, Context& ctx);
/// mvtwin calibrate (tools/calibrate.cpp).
void register_calibrate(CLI::App& app, Context& ctx);
/// mvtwin bench calibrate (tools/bench_calibrate.cpp), under the bench command.
void register_bench_calibrate(CLI::App& bench, Context& ctx);
/// mvtwin clip (tools/clip.cpp).
void register_clip(CLI::App& app, Context& ctx);
/// mvtwin render-tee (tools/render_tee.cpp).
void register_render_tee(CLI::App& app, Context& ctx);
/// Throws mvtwin::Error when `path` exists and `force` is not set.
void refuse_overwrite_path(const std::filesystem::path& path, bool force);

}  // namespace mvtwin::tools
