#include "mvtwin/core/rng.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace mvtwin {

int Rng::uniform_int(int lo, int hi) {
  const auto span = static_cast<std::uint64_t>(hi - lo) + 1;
  return lo + static_cast<int>(engine_() % span);  // bias < 2^-50 for small spans
}

double Rng::normal(double mean, double sd) {
  if (has_spare_) {
    has_spare_ = false;
    return mean + sd * spare_;
  }
  double u1 = uniform();
  while (u1 <= 0.0) u1 = uniform();
  const double u2 = uniform();
  const double r = std::sqrt(-2.0 * std::log(u1));
  const double a = 2.0 * std::numbers::pi * u2;
  spare_ = r * std::sin(a);
  has_spare_ = true;
  return mean + sd * r * std::cos(a);
}

double Rng::truncated_normal(double mean, double sd, double lo, double hi) {
  for (int i = 0; i < 64; ++i) {
    const double x = normal(mean, sd);
    if (x >= lo && x <= hi) return x;
  }
  return std::clamp(mean, lo, hi);
}

}  // namespace mvtwin
