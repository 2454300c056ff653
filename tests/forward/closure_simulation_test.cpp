#include "mvtwin/forward/closure_simulation.h"

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "mvtwin/core/error.h"
#include "mvtwin/core/virtual_patient.h"

namespace mvtwin::forward {
namespace {

// A deliberately small model so that the tests stay fast.
ClosureOptions small_options() {
  ClosureOptions o;
  o.model.ures = 8;
  o.model.vres = 5;
  o.model.order = TetOrder::kQuadratic;
  o.dt = 0.02;
  o.stretch = 2.0;
  return o;
}

TEST(ClosureSimulation, NoLoadNoMotionStaysAtRest) {
  const Patient p = make_virtual_patient(31);
  ClosureOptions o = small_options();
  o.annulus_motion = false;
  o.papillary_motion = false;
  ValveParameters par = p.truth->parameters;
  par.peak_pressure_mpa = 0.0;
  for (double& f : par.restlength_factor) f = 3.0;  // slack chordae
  const ClosureResult r = simulate_closure(p.sequence, par, o);
  ASSERT_EQ(r.summary.status, ClosureStatus::kConverged) << r.summary.reason;
  const LeafletGrid& first = r.samples.front().la_surface;
  const LeafletGrid& last = r.samples.back().la_surface;
  EXPECT_LT((first.points() - last.points()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_GT(r.summary.steps, 0);
}

TEST(ClosureSimulation, SameInputSameOutput) {
  const Patient p = make_virtual_patient(32);
  const ClosureOptions o = small_options();
  const ClosureResult a = simulate_closure(p.sequence, p.truth->parameters, o);
  const ClosureResult b = simulate_closure(p.sequence, p.truth->parameters, o);
  EXPECT_EQ(a.summary.status, b.summary.status);
  EXPECT_EQ(a.summary.steps, b.summary.steps);
  EXPECT_EQ(a.positions, b.positions);
}

// With the boundary held and the chordae slack, only the pressure acts: the work it does on the
// displacement, sum over the ventricular faces of p A (-n) . u, must be positive (f^T K^-1 f > 0
// in the linear regime). (The open valve is a closed conical skirt: pressure loads it mostly
// in hoop compression, so the tips need not rise; the work must still be positive.)
TEST(ClosureSimulation, PressureDoesPositiveWork) {
  const Patient p = make_virtual_patient(33);
  ClosureOptions o = small_options();
  o.annulus_motion = false;
  o.papillary_motion = false;
  ValveParameters par = p.truth->parameters;
  par.peak_pressure_mpa *= 0.02;
  for (double& f : par.restlength_factor) f = 3.0;
  const ClosureResult r = simulate_closure(p.sequence, par, o);
  ASSERT_EQ(r.summary.status, ClosureStatus::kConverged) << r.summary.reason;
  const ValveModel m = build_valve_model(p.sequence, o.model);
  double work = 0.0, moved = 0.0;
  for (const Eigen::Vector3i& f : m.ventricular_faces) {
    const Eigen::Vector3d a = m.mesh.V.row(f[0]), b = m.mesh.V.row(f[1]), c = m.mesh.V.row(f[2]);
    const Eigen::Vector3d load = -0.5 * (b - a).cross(c - a);  // direction of p A (-n)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d u = r.positions.segment<3>(3 * f[k]) - m.mesh.V.row(f[k]).transpose();
      work += load.dot(u) / 3.0;
      moved = std::max(moved, u.norm());
    }
  }
  EXPECT_GT(moved, 1e-3);  // it did move
  EXPECT_GT(work, 0.0);
}

TEST(ClosureSimulation, FailureIsAStatusWithAReasonNeverAnAbort) {
  const Patient p = make_virtual_patient(34);
  ClosureOptions o = small_options();
  o.max_step_halvings = 1;
  ValveParameters par = p.truth->parameters;
  par.peak_pressure_mpa = 50.0;  // ~375,000 mmHg: must invert elements
  const ClosureResult r = simulate_closure(p.sequence, par, o);
  EXPECT_EQ(r.summary.status, ClosureStatus::kFailed);
  EXPECT_NE(r.summary.reason.find("inverted"), std::string::npos) << r.summary.reason;
  EXPECT_TRUE(r.positions.allFinite());
}

TEST(ClosureSimulation, InvalidOptionsAreNamed) {
  const Patient p = make_virtual_patient(35);
  ClosureOptions o = small_options();
  o.dt = -1;
  EXPECT_THROW(simulate_closure(p.sequence, p.truth->parameters, o), Error);
  o = small_options();
  o.ruptured_marginal_chordae = {99};
  EXPECT_THROW(simulate_closure(p.sequence, p.truth->parameters, o), Error);
  Patient q = p;
  q.sequence.first_closed = -1;
  EXPECT_THROW(simulate_closure(q.sequence, p.truth->parameters, small_options()), Error);
}

}  // namespace
}  // namespace mvtwin::forward
