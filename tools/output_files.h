#pragma once
// Result files the commands share: a simulation file with the command's provenance, and JSON
// summaries, both written atomically.
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "mvtwin/core/cache_key.h"
#include "mvtwin/core/patient.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::tools {

/// Writes `result` of `patient` (read from `patient_file`) as a simulation file recording the
/// options, parameters, mvtwin version, `command_line`, time and the patient's seed.
void write_simulation_result(const std::filesystem::path& out, const forward::ClosureResult& result,
                             const forward::ClosureOptions& options,
                             const ValveParameters& parameters, const Patient& patient,
                             const std::string& patient_file, const std::string& command_line);

/// The JSON summary written beside a result file: the same path with the extension .json.
std::filesystem::path summary_path(const std::filesystem::path& result_file);

/// What a script reads of a simulation: patient, provenance (version, command, time, seed),
/// status, parameters, the options that change results, timing, and the closed valve's
/// regurgitant orifice at the top level (aroa_mm2, eroa_mm2, openings_mm2, mr_grade,
/// coaptation_length_mm, ...; null when it was not measured).
nlohmann::json simulation_summary_json(const forward::ClosureResult& result,
                                       const forward::ClosureOptions& options,
                                       const ValveParameters& parameters, const Patient& patient,
                                       const std::string& command_line);

/// "input ASSUMED (...): names" for a patient with landmarks estimated rather than observed, ""
/// otherwise: recorded in every result file made from it.
std::string assumed_note(const Patient& patient);

/// Writes `j` (indented by `indent`) to `path` atomically; nothing for an empty path.
void write_json_file(const std::filesystem::path& path, const nlohmann::json& j, int indent = 2);

using mvtwin::cache_key;  // core/cache_key.h

}  // namespace mvtwin::tools
