#pragma once
// Wall time since a point, in seconds (the closures, solvers and studies report it).

#include <chrono>

namespace mvtwin {

/// Seconds of the steady clock since t0.
inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace mvtwin
