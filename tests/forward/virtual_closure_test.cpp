#include "mvtwin/forward/virtual_closure.h"

#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "mvtwin/core/closure_measures.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
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

TEST(VirtualClosure, AFailedObservationIsRetriedWithSaferStepsAndSaysSo) {
  // Fixed steps of 0.05 s and no step halvings: virtual patient 1's closure drives a node
  // through the other leaflet at t = 0.6 s. The first retry (3 halvings, smaller settling
  // steps) observes it; the patient records which setting did, through its file too.
  VirtualClosureOptions o = coarse(0.5);
  o.simulation.step_error_mm = 0;
  o.simulation.max_step_halvings = 0;
  const Patient base = make_virtual_patient(1);
  const ClosureResult failing = simulate_closure(base.sequence, base.truth->parameters,
                                                 observation_attempts(o.simulation)[0].simulation);
  ASSERT_FALSE(failing.summary.converged()) << "the test needs a setting that fails as given";
  Patient p = base;
  simulate_observed_closure(&p, o);
  EXPECT_EQ(p.truth->observed_with.rfind("retry 1: max_step_halvings 3", 0), 0u)
      << p.truth->observed_with;
  EXPECT_NE(p.truth->closed_frames.find("observed by retry 1"), std::string::npos);
  EXPECT_NE(p.truth->closed_frames.find("as given: "), std::string::npos)
      << "the failure that caused the retry is named: " << p.truth->closed_frames;
  const ValveSequence& s = p.sequence;
  EXPECT_TRUE(s.frames[s.first_closed].la_surface.has_value());
  const auto file = std::filesystem::temp_directory_path() / "mvtwin_observed_retry.h5";
  write_patient(file, p);
  EXPECT_EQ(read_patient(file, false).truth->observed_with, p.truth->observed_with);
  std::filesystem::remove(file);
  // The model as given, when it succeeds, records no retry (and the file no attribute).
  Patient q = base;
  simulate_observed_closure(&q, coarse(0.5));
  EXPECT_TRUE(q.truth->observed_with.empty());

  // The ladder: the same model, stepped more carefully each time, recorded at the same times.
  const auto a = observation_attempts(o.simulation);
  ASSERT_EQ(a.size(), 4u);
  EXPECT_TRUE(a[0].setting.empty());
  EXPECT_EQ(a[1].simulation.max_step_halvings, 3);
  EXPECT_DOUBLE_EQ(a[2].simulation.dt, 0.025);
  EXPECT_GE(a[2].simulation.newton_iterations, 2);
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_DOUBLE_EQ(a[k].simulation.contact.wall_factor, o.simulation.contact.wall_factor);
    EXPECT_DOUBLE_EQ(a[k].simulation.contact.ccd_depth_mm, 0.0);
  }
  // The last changes the contact wall only, and says so.
  EXPECT_DOUBLE_EQ(a[3].simulation.contact.wall_factor, 10 * o.simulation.contact.wall_factor);
  EXPECT_DOUBLE_EQ(a[3].simulation.contact.ccd_depth_mm, 0.1);
  EXPECT_DOUBLE_EQ(a[3].simulation.dt, o.simulation.dt);
  EXPECT_EQ(a[3].simulation.max_step_halvings, o.simulation.max_step_halvings);
  EXPECT_EQ(a[3].setting, "retry 3: contact_wall_factor 1000, contact_ccd_depth_mm 0.1");
  for (const auto& x : a) {
    EXPECT_EQ(x.simulation.model.ures, 20);
    EXPECT_EQ(x.simulation.contact.stiffness_factor, o.simulation.contact.stiffness_factor);
    EXPECT_DOUBLE_EQ(x.simulation.settle_mm, o.simulation.settle_mm);
  }
}

TEST(VirtualClosure, InputNoSettingMendsIsNotRetried) {
  VirtualClosureOptions o = coarse(0.5);
  o.simulation.density = -1;  // impossible: refused as input, not retried
  Patient p = make_virtual_patient(1);
  try {
    simulate_observed_closure(&p, o);
    FAIL() << "an impossible density was observed";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("density must be positive"), std::string::npos) << m;
    EXPECT_EQ(m.find("retry"), std::string::npos) << m;
  }
  EXPECT_FALSE(p.sequence.frames[p.sequence.first_closed].la_surface.has_value())
      << "a failed observation leaves the patient as it was";
}

TEST(VirtualClosure, RealPatientsAreRefused) {
  Patient p = make_virtual_patient(2);
  p.synthetic = false;
  p.truth.reset();
  EXPECT_THROW(simulate_observed_closure(&p, coarse(0.5)), Error);
}

}  // namespace
}  // namespace mvtwin::forward
