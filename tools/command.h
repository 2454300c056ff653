#pragma once
// What every mvtwin command shares. A command lives in one file, tools/NAME.cpp, with its
// header tools/NAME.h declaring
//   struct NameArgs : CommandArgs { ... };      everything the command line can set
//   int run_name(const NameArgs& args);         the work, callable in-process (tests)
//   void register_name(CLI::App& parent, Context& ctx);
// register_name binds the options to a NameArgs and, when the command is chosen, sets ctx.run
// to call run_name on it (run_on_parse). run_name returns an exit status (exit_codes.h) and
// throws mvtwin::Error for bad input.
#include <filesystem>
#include <functional>
#include <memory>
#include <set>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "mvtwin/core/patient.h"
#include "mvtwin/core/virtual_patient.h"

namespace mvtwin::tools {

/// What the chosen command will run, and the command line recorded in provenance.
struct Context {
  std::string command_line;
  std::function<int()> run;
};

/// The base of every command's arguments: the command line, recorded in what it writes.
struct CommandArgs {
  std::string command_line;
  /// The options given on the command line (long names, "--patients"): for commands whose
  /// --quick size keeps its own values unless an option is given.
  std::set<std::string> given;
};

/// When `cmd` is the chosen command, ctx.run becomes `run(*args)` (with the command line).
template <class Args>
void run_on_parse(CLI::App* cmd, Context& ctx, std::shared_ptr<Args> args,
                  int (*run)(const Args&)) {
  cmd->callback([cmd, &ctx, args, run] {
    args->command_line = ctx.command_line;
    for (const CLI::Option* o : cmd->get_options()) {
      if (o->count() > 0) args->given.insert(o->get_name());
    }
    ctx.run = [args, run] { return run(*args); };
  });
}

/// What every JSON result of a command records about its making: mvtwin_version, command,
/// created_utc (add the seed, the source, ... where there is one).
nlohmann::json provenance(const std::string& command_line);

/// Reads a patient file; with `use_detected` its detected sequence (mvtwin detect) replaces the
/// stored one for this run (the file is not changed). Throws mvtwin::Error when there is none.
/// Prints the landmarks that are assumed rather than observed.
Patient read_patient_for_run(const std::filesystem::path& path, bool use_detected);

/// Throws mvtwin::Error when `path` exists and `force` is not set.
void refuse_overwrite(const std::filesystem::path& path, bool force);

/// The (u, v) grid resolution options shared by the commands that make a valve.
void add_grid_options(CLI::App* cmd, int& ures, int& vres);
/// --taut-chordae / --no-taut-chordae and --commissure-clearance (VirtualPatientOptions: the
/// closing anatomy, on by default).
void add_closing_anatomy_options(CLI::App* cmd, VirtualPatientOptions& o);
/// --tune-normal-chordae / --no-tune-normal-chordae (on by default).
void add_tune_normal_option(CLI::App* cmd, bool& tune);

/// What tuning a normal virtual valve's chordae did (tune_normal_if_asked).
struct NormalTuning {
  bool tuned = false;  ///< false: not asked, not a normal virtual valve with chordae lengths
  double eroa_before_mm2 = 0, eroa_mm2 = 0, seconds = 0;
  int closures = 0, kept = 0;
};
/// With `tune`, sizes the marginal chordae of `p` when it is a normal virtual valve
/// (forward::tune_normal_virtual_patient) on a ures x vres model, printing one line. Throws
/// mvtwin::Error when the tuning's first closure fails.
NormalTuning tune_normal_if_asked(Patient* p, bool tune, int ures, int vres);

}  // namespace mvtwin::tools
