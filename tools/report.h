#pragma once
// Every human-readable report the commands print, in one place: what a patient, a simulation,
// a closure or a calibration looks like on a terminal.
#include <ostream>
#include <string>

#include <nlohmann/json.hpp>

#include "mvtwin/core/calibration_file.h"
#include "mvtwin/core/patient.h"
#include "mvtwin/core/simulation_file.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::tools {

/// `v` with `precision` decimals; "n/a" for NaN.
std::string fixed(double v, int precision = 2);

/// The landmarks estimated from anatomy rather than observed, if any: every report that uses
/// them says so, because the papillary tips drive the closure.
void print_assumed(const Patient& patient, std::ostream& os);

/// mvtwin info of a patient file: provenance, sequence, annulus and leaflet measures at
/// end-diastole and the first closed frame, ruptures, images, hidden truth.
void print_patient(const Patient& patient, std::ostream& os);

/// mvtwin info of a simulation file: provenance, status, settings, samples, end state.
void print_simulation_record(const SimulationRecord& record, std::ostream& os);

/// One line on a closed valve's regurgitant orifice: AROA, EROA and grade, the openings (area and
/// where along the coaptation line), coaptation length and depth, the seal distance.
std::string orifice_line(const RegurgitantOrifice& orifice);
/// The same for a JSON summary: aroa_mm2, eroa_mm2, openings_mm2 (largest first), openings,
/// mr_grade, coaptation_length_mm, coaptation_depth_mm (null when nothing coapts), ...
nlohmann::json orifice_json(const RegurgitantOrifice& orifice);

/// What mvtwin simulate prints after a closure: status, samples, orifice, clips.
void print_closure(const forward::ClosureResult& result, std::ostream& os);

/// The fitted parameters with their uncertainty and the strongest trade-offs.
void print_calibration(const CalibrationRecord& record, std::ostream& os);

}  // namespace mvtwin::tools
