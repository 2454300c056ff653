#pragma once
#include <stdexcept>
#include <string>

namespace mvtwin {

/// Bad input that a user can fix: a missing or malformed file, a wrong shape, a NaN, an
/// impossible parameter. The message names the file (or object) and the problem.
/// Numerical failures of a simulation are not errors: they are reported as a status.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace mvtwin
