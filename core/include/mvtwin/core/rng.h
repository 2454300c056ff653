#pragma once
#include <cstdint>
#include <random>

namespace mvtwin {

/// Seeded random numbers that are identical on every platform and standard library:
/// std::mt19937_64's output is fixed by the standard, but std::*_distribution are not,
/// so the distributions are written out here.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : engine_(seed) {}

  /// Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  /// Uniform in [lo, hi).
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  /// Integer uniform in [lo, hi] (inclusive).
  int uniform_int(int lo, int hi);
  /// Normal(mean, sd) by the Box-Muller transform.
  double normal(double mean = 0.0, double sd = 1.0);
  /// Normal(mean, sd) truncated to [lo, hi] by rejection (falls back to clamping).
  double truncated_normal(double mean, double sd, double lo, double hi);

 private:
  std::mt19937_64 engine_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

}  // namespace mvtwin
