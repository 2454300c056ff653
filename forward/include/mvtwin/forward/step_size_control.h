#pragma once
// Error-controlled step sizes for the closure's implicit Euler steps.
#include <algorithm>
#include <cmath>

namespace mvtwin::forward {

/// Chooses the size of each implicit Euler step from an estimate of its local error.
///
/// Implicit Euler advances x1 = x0 + h v1; the trapezoidal rule, one order higher, would take
/// x0 + h (v0 + v1) / 2. Their difference, h/2 |v1 - v0| (the largest over the free nodes, mm),
/// estimates the step's local position error, which grows as h^2. A step is accepted when the
/// estimate is within the tolerance or the step is already the smallest allowed; the next step
/// is scaled by 0.9 sqrt(tolerance / estimate), at most doubled, and rounded down to min_h times
/// a power of two no larger than max_h.
///
/// min_h is the closure's dt, the paper's step: steps grow beyond it where the motion is smooth
/// (the open valve filling and the closed valve settling) and return to it at impacts. Failed
/// steps (an inverted element, a leaflet crossing) are halved below it by the driver as before.
class StepSizeControl {
 public:
  /// tolerance_mm = 0: fixed steps of min_h (the paper's scheme).
  StepSizeControl(double min_h, double max_h, double tolerance_mm)
      : min_h_(min_h), max_h_(max_h > min_h ? max_h : min_h), tol_(tolerance_mm) {}

  bool adaptive() const { return tol_ > 0.0; }
  double min_step() const { return min_h_; }
  double max_step() const { return max_h_; }

  /// Whether a step of size h whose local error estimate is error_mm stands.
  bool accept(double h, double error_mm) const {
    return !adaptive() || error_mm <= tol_ || h <= min_h_ * (1.0 + 1e-9);
  }

  /// The size of the next step (or of the retry, after a rejected step) after a step of h.
  double next(double h, double error_mm) const {
    if (!adaptive()) return min_h_;
    double factor = 2.0;  // no error: doubled
    if (std::isnan(error_mm))
      factor = 0.25;  // no estimate: back off
    else if (error_mm > 0.0)
      factor = std::clamp(0.9 * std::sqrt(tol_ / error_mm), 0.25, 2.0);
    // Rounded down to min_h times a power of two: the step matrix, and so the linear
    // solver's reused factorization, changes only when the level does.
    const double want = h * factor;
    double n = min_h_;
    while (2.0 * n <= want * (1.0 + 1e-9) && 2.0 * n <= max_h_ * (1.0 + 1e-9)) n *= 2.0;
    return n;
  }

 private:
  double min_h_, max_h_, tol_;
};

}  // namespace mvtwin::forward
