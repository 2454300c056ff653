#pragma once
#include <string>
#include <utility>
#include <vector>

#include "mvtwin/core/valve_parameters.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::forward {

/// Sets one simulation option or patient parameter from "name=value" (the command line's
/// --set). Names are the ClosureOptions / ModelOptions fields (dt, stretch, ures, vres, layers,
/// order, solver, contact, contact_friction, ...) and the ValveParameters names
/// (restlength_factor_anterolateral_marginal, ..., peak_pressure in MPa, or peak_pressure_mmhg).
/// Throws mvtwin::Error naming an unknown name or a value that does not parse; the options'
/// validator checks ranges.
void apply_setting(const std::string& assignment, ClosureOptions* options,
                   ValveParameters* parameters);

/// Every settable option with its current value, as text (for reports and result files).
std::vector<std::pair<std::string, std::string>> describe_options(const ClosureOptions& options);

}  // namespace mvtwin::forward
