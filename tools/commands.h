#pragma once
// Every mvtwin command, registered on one CLI::App (main.cpp, and the tests that run the
// commands in-process). A command NAME lives in tools/NAME.cpp (command.h says how).
#include <CLI/CLI.hpp>

#include "command.h"

namespace mvtwin::tools {

/// Registers every command on `app`; after app.parse, ctx.run runs the chosen one.
void add_commands(CLI::App& app, Context& ctx);

/// mvtwin study cohort | ... (tools/study.cpp).
void register_study(CLI::App& app, Context& ctx);

}  // namespace mvtwin::tools
