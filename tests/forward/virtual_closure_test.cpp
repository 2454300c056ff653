#include "mvtwin/forward/virtual_closure.h"

#include <cmath>

#include <gtest/gtest.h>

#include "mvtwin/core/closure_measures.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/virtual_patient.h"

namespace mvtwin::forward {
namespace {

VirtualClosureOptions coarse(double noise) {
  VirtualClosureOptions o;
  o.simulation = ClosureOptions{};  // a coarse model keeps the test fast
  o.simulation.model.ures = 20;
  o.simulation.model.vres = 10;
  o.simulation.dt = 0.05;
  o.noise_mm = noise;
  return o;
}

TEST(VirtualClosure, ClosingFramesAreSimulatedClosedAndNoisy) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "two closures take minutes under AddressSanitizer";
#endif
  const Patient base = make_virtual_patient(1);
  const ValveSequence& s0 = base.sequence;
  ASSERT_FALSE(s0.frames[s0.first_closed].la_surface.has_value());
  Patient clean = base, noisy = base;
  simulate_observed_closure(&clean, coarse(0.0));
  simulate_observed_closure(&noisy, coarse(0.5));
  const ValveSequence& s = clean.sequence;
  for (int f = 0; f < s.num_frames(); ++f) {
    const bool expect = f <= s.first_closed;  // open frames and the closing ones
    EXPECT_EQ(s.frames[f].la_surface.has_value(), expect) << "frame " << f;
  }
  // The first closed frame is closed; its annulus row is the frame's annulus.
  const ValveFrame& fc = s.frames[s.first_closed];
  const ClosureMeasures m = measure_closure(fc);
  EXPECT_LT(m.orifice_area_mm2, 0.03 * m.annulus_area_mm2);
  EXPECT_EQ(fc.la_surface->points().topRows(s.ures), fc.annulus);
  // Noise: RMS displacement ~ the requested SD, annulus untouched.
  const auto& a = fc.la_surface->points();
  const auto& b = noisy.sequence.frames[s.first_closed].la_surface->points();
  const double rms = std::sqrt((a - b).rowwise().squaredNorm().mean());
  EXPECT_NEAR(rms, 0.5, 0.1);
  EXPECT_EQ((a.topRows(s.ures) - b.topRows(s.ures)).norm(), 0.0);
  EXPECT_NE(clean.truth->closed_frames.find("simulated with the hidden parameters"),
            std::string::npos);
}

TEST(VirtualClosure, RealPatientsAreRefused) {
  Patient p = make_virtual_patient(2);
  p.synthetic = false;
  p.truth.reset();
  EXPECT_THROW(simulate_observed_closure(&p, coarse(0.5)), Error);
}

}  // namespace
}  // namespace mvtwin::forward
