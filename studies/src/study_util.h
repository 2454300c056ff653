#pragma once
// Internal helpers the studies share.
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mvtwin/core/valve_parameters.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::studies::detail {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Every option of a simulation model as name -> text (configurations, reports).
nlohmann::json describe(const forward::ClosureOptions& o);
/// Every parameter as name -> value.
nlohmann::json parameters_json(const ValveParameters& p);

struct Stats {
  int n = 0;
  double mean = kNaN, sd = kNaN, min = kNaN, max = kNaN;
};
/// Mean, sample SD and range of the finite values.
Stats stats(const std::vector<double>& v);
/// {"n", "mean", "sd", "min", "max"} (null when n = 0).
nlohmann::json stats_json(const std::vector<double>& v);

/// The provenance every study file records.
nlohmann::json provenance(const std::string& command, const std::string& workers, double wall_s);

}  // namespace mvtwin::studies::detail
