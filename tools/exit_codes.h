#pragma once

namespace mvtwin::tools {

/// The exit status of every mvtwin command (README.md, "Exit status").
enum ExitCode : int {
  kExitOk = 0,        ///< done (also --help and --version)
  kExitInput = 1,     ///< bad input: a missing or malformed file, a refused value (mvtwin::Error)
  kExitUsage = 2,     ///< bad command line: unknown option, missing or malformed argument
  kExitInternal = 3,  ///< an internal error (a bug): please report it with the command line
  kExitFailed = 4,    ///< the work ran but a simulation (or some patients of a batch) failed;
                      ///< the result files say which and why
};

}  // namespace mvtwin::tools
