#pragma once
// The quiet NaN that marks a value not measured (a failed run's error, a missing column).

#include <limits>

namespace mvtwin {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace mvtwin
