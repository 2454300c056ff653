#pragma once
// What the `mvtwin study NAME` commands share (tools/study.cpp); each study is tools/study_NAME.h.
#include <string>

#include <CLI/CLI.hpp>

#include "commands.h"
#include "mvtwin/forward/closure_simulation.h"
#include "mvtwin/studies/study_folder.h"
#include "mvtwin/studies/work_pool.h"

namespace mvtwin::tools {

/// A progress line per event on stderr, prefixed by the rank under MPI.
studies::StudyProgress progress_printer(const studies::WorkPool& pool);

/// Applies a name=value model option; refuses a patient parameter (naming why) instead of
/// dropping it.
void apply_model_setting(const std::string& assignment, forward::ClosureOptions* options,
                         const std::string& why);

}  // namespace mvtwin::tools
