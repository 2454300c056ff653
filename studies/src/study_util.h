#pragma once
// Internal helpers the studies share.
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mvtwin/core/nan.h"
#include "mvtwin/core/patient.h"
#include "mvtwin/core/stopwatch.h"
#include "mvtwin/core/valve_parameters.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/forward/closure_simulation.h"
#include "mvtwin/forward/virtual_closure.h"

namespace mvtwin::studies::detail {

using mvtwin::kNaN;

using mvtwin::seconds_since;

/// Every option of a simulation model as name -> text (configurations, reports).
nlohmann::json describe(const forward::ClosureOptions& o);
/// Every parameter as name -> value.
nlohmann::json parameters_json(const ValveParameters& p);
/// Adds to a study's configuration the calibration's start scans that a fit of `fit` uses
/// (inverse::CalibrationOptions' defaults) where they changed after studies were made with it:
/// "modulus_scan" when the leaflets' moduli are fitted, so that a folder calibrated without it
/// is refused.
void add_calibration_scans(nlohmann::json* config, const std::string& fit);

struct Stats {
  int n = 0;
  double mean = kNaN, sd = kNaN, min = kNaN, max = kNaN;
};
/// Mean, sample SD and range of the finite values.
Stats stats(const std::vector<double>& v);
/// {"n", "mean", "sd", "min", "max"} (null when n = 0).
nlohmann::json stats_json(const std::vector<double>& v);

/// `v` as JSON, null when not finite (JSON has no NaN).
nlohmann::json nullable(double v);
/// `j[key]` as a number; NaN when absent, null or not a number.
double number_at(const nlohmann::json& j, const char* key);
/// "mean ± SD" of a stats_json object with `digits` decimals; "n/a" without values.
std::string stats_text(const nlohmann::json& s, int digits = 2);

/// The patient of a one-patient study: virtual patient `index` of cohort `seed` at its hidden
/// parameters, or `file` at the default parameters. Throws mvtwin::Error for an unreadable
/// file.
Patient study_patient(std::uint64_t seed, int index, const std::filesystem::path& file,
                      ValveParameters* parameters);

/// Where cohort member `member`'s observed closure is cached in `cache`: named by the
/// observation model (and, for a normal valve whose chordae the observation tunes, the tuning
/// rule's edition), so that studies and runs with the same model share it.
std::filesystem::path observed_file(const std::filesystem::path& cache, const CohortMember& member,
                                    const forward::VirtualClosureOptions& observation);
/// Makes virtual patient `index` of cohort `seed` observed by `observation` into `file`, unless a
/// readable file with its closed frame is already there (a damaged one is made again). Returns
/// the seconds spent simulating (0 when cached). Throws mvtwin::Error when the observation
/// fails.
double ensure_observed(const std::filesystem::path& file, std::uint64_t seed, int index,
                       const forward::VirtualClosureOptions& observation);

/// The provenance every study file records.
nlohmann::json provenance(const std::string& command, const std::string& workers, double wall_s);

}  // namespace mvtwin::studies::detail
