// mvtwin: the command line, thin over the libraries. Errors go to stderr; the exit status is one
// of tools/exit_codes.h (README.md, "Exit status").
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>

#include <CLI/CLI.hpp>

#include "commands.h"
#include "exit_codes.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/version.h"

int main(int argc, char** argv) {
  CLI::App app{
      "mvtwin: patient-specific mitral valve biomechanics (Mansi et al. 2012, re-created)"};
  app.set_version_flag("--version", std::string(mvtwin::kVersion));
  app.require_subcommand(1);
  app.footer("Run 'mvtwin <command> --help' for a command's options and an example.");
  mvtwin::tools::Context ctx;
  for (int i = 0; i < argc; ++i) ctx.command_line += (i ? " " : "") + std::string(argv[i]);
  mvtwin::tools::add_commands(app, ctx);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // CLI11 prints the help, the version or the problem; --help and --version are not errors.
    return app.exit(e) == 0 ? mvtwin::tools::kExitOk : mvtwin::tools::kExitUsage;
  }
  try {
    return ctx.run();
  } catch (const mvtwin::Error& e) {
    std::cerr << "mvtwin: error: " << e.what() << "\n";
    return mvtwin::tools::kExitInput;
  } catch (const std::exception& e) {
    std::cerr << "mvtwin: internal error: " << e.what() << "\n";
    return mvtwin::tools::kExitInternal;
  }
}
