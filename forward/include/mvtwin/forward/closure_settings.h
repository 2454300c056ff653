#pragma once
#include <string>
#include <utility>
#include <vector>

#include "mvtwin/core/valve_parameters.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::forward {

/// Sets one simulation option from "name=value" (the command line's --set): the ClosureOptions
/// and ModelOptions names (dt, stretch, ures, vres, layers, order, solver, contact,
/// contact_friction, clips, ...). Throws mvtwin::Error naming an unknown name or a value that does
/// not parse; a patient parameter's name is refused as such, with `context` saying why the
/// command takes none (it would otherwise be dropped). The options' validator checks ranges.
void apply_option(const std::string& assignment, ClosureOptions* options,
                  const std::string& context = "this command takes simulation options only");

/// Sets one patient parameter from "name=value": the ValveParameters names
/// (restlength_factor_anterolateral_marginal, ..., peak_pressure in MPa) or peak_pressure_mmhg.
/// Throws mvtwin::Error naming an unknown name (an option's name as such) or a bad value.
void apply_parameter(const std::string& assignment, ValveParameters* parameters);

/// An option or a parameter, by its name (for commands that take both).
void apply_setting(const std::string& assignment, ClosureOptions* options,
                   ValveParameters* parameters);

bool is_option_name(const std::string& name);
bool is_parameter_name(const std::string& name);

/// Every settable option with its current value, as text (for reports and result files); the
/// static solve's (static_rest, static_*) only when static_rest is on.
std::vector<std::pair<std::string, std::string>> describe_options(const ClosureOptions& options);
/// Whether an option can change a simulation's result (threads cannot).
bool affects_results(const std::string& option_name);
/// Of described options (describe_options(), or a result file's), those that can change a
/// result: without threads, and without the settling options while settling is off (settle_mm
/// 0 or absent), so that descriptions made before settling existed still match.
std::vector<std::pair<std::string, std::string>> result_options(
    std::vector<std::pair<std::string, std::string>> described);
/// result_options(describe_options(options)): for cache keys and for deciding whether a stored
/// run is the one asked for.
std::vector<std::pair<std::string, std::string>> describe_result_options(
    const ClosureOptions& options);

}  // namespace mvtwin::forward
