#include "mvtwin/forward/clip_device.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "mvtwin/core/error.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/forward/chorda.h"
#include "mvtwin/forward/closure_scene.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::forward {
namespace {

TEST(ClipDevices, TheTableHoldsTheG4AndPascalSizes) {
  const auto& t = clip_devices();
  ASSERT_EQ(t.size(), 6u);
  std::set<std::string> names;
  for (const ClipDevice& d : t) {
    names.insert(d.name);
    EXPECT_GT(d.width_mm, 0) << d.name;
    EXPECT_GT(d.arm_length_mm, 0) << d.name;
    EXPECT_GE(d.spacer_mm, 0) << d.name;
    EXPECT_FALSE(d.source.empty()) << d.name;
  }
  EXPECT_EQ(names.size(), t.size()) << "device names are unique";
  // MitraClip G4: NT/XT arms 4 mm wide, NTW/XTW 6 mm; NT/NTW 9 mm long, XT/XTW 12 mm.
  EXPECT_EQ(clip_device("NT").width_mm, 4.0);
  EXPECT_EQ(clip_device("nt").arm_length_mm, 9.0);  // case-insensitive
  EXPECT_EQ(clip_device("XTW").width_mm, 6.0);
  EXPECT_EQ(clip_device("XTW").arm_length_mm, 12.0);
  EXPECT_EQ(clip_device("XTW").spacer_mm, 0.0);
  EXPECT_EQ(clip_device("P10").width_mm, 10.0);
  EXPECT_GT(clip_device("ACE").spacer_mm, 0.0);
  try {
    clip_device("MitraClip");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("NTW"), std::string::npos) << "lists the known names";
  }
}

TEST(TieGradient, ForceAndTangentMatchFiniteDifferencesPullingAndPushing) {
  const double k = 9.8, L0 = 2.0;
  const Eigen::Vector3d a(0.3, -0.2, 0.1);
  for (double stretch : {1.3, 0.6}) {  // pulling, pushing
    const Eigen::Vector3d b = a + stretch * L0 * Eigen::Vector3d(0.6, 0.0, 0.8);
    Eigen::Matrix<double, 6, 1> g;
    Eigen::Matrix<double, 6, 6> H;
    tie_gradient(k, L0, a, b, &g, &H);
    Eigen::Matrix<double, 6, 1> x;
    x << a, b;
    auto energy = [&](const Eigen::Matrix<double, 6, 1>& y) {
      double e = 0;
      tie_gradient(k, L0, y.head<3>(), y.tail<3>(), nullptr, nullptr, &e);
      return e;
    };
    for (int i = 0; i < 6; ++i) {
      Eigen::Matrix<double, 6, 1> xp = x, xm = x;
      const double h = 1e-6;
      xp[i] += h;
      xm[i] -= h;
      EXPECT_NEAR((energy(xp) - energy(xm)) / (2 * h), g[i], 1e-6) << stretch << " " << i;
    }
    // Along the tie the tangent is k, pulling or pushing (its geometric term only when pulling).
    const Eigen::Vector3d n = (b - a).normalized();
    Eigen::Matrix<double, 6, 1> dn;
    dn << -n, n;
    EXPECT_NEAR(dn.dot(H * dn), 4.0 * k, 1e-9);
    EXPECT_GE(H.selfadjointView<Eigen::Lower>().eigenvalues().minCoeff(), -1e-9);
    // The force's sign: a stretched tie pulls b back towards a, a compressed one pushes it away.
    EXPECT_EQ(g.tail<3>().dot(n) > 0, stretch > 1.0);
  }
}

ClosureOptions device_options(const ClipDevice& d, double position) {
  ClosureOptions o;
  ClipOptions c;
  c.anterior_s = 0.5 * position;
  c.posterior_s = 1.0 - 0.5 * position;
  c.width_mm = d.width_mm;
  c.arm_length_mm = d.arm_length_mm;
  c.spacer_mm = d.spacer_mm;
  c.device = d.name;
  o.clips.push_back(c);
  return o;
}

TEST(DeviceClip, GraspsABandAsWideAsTheArmsAndAsDeepAsTheLeafletInserts) {
  const Patient p = make_virtual_patient(1);
  const ValveSequence& seq = p.sequence;
  for (const char* name : {"NT", "XTW", "P10"}) {
    SCOPED_TRACE(name);
    const ClipDevice& d = clip_device(name);
    const ClosureOptions o = device_options(d, 0.5);
    const ClosureScene sc = make_closure_scene(seq, p.truth->parameters, o);
    ASSERT_EQ(sc.grasps.size(), 1u);
    const ClipGrasp& g = sc.grasps.front();
    // The insertion from the geometry, computed here independently.
    const LeafletGrid& ed = *seq.frames[static_cast<size_t>(seq.end_diastole)].la_surface;
    const auto closed =
        resample_closed_curve(seq.frames[static_cast<size_t>(seq.first_closed)].annulus, 512);
    const double La = ed.radial_length_at(0.25), Lp = ed.radial_length_at(0.75);
    const double chord = (closed.row(128) - closed.row(384)).norm();
    EXPECT_NEAR(g.anterior_insertion_mm,
                std::min(d.arm_length_mm, La * (La + Lp - chord) / (La + Lp)), 0.05);
    EXPECT_NEAR(g.posterior_insertion_mm,
                std::min(d.arm_length_mm, Lp * (La + Lp - chord) / (La + Lp)), 0.05);
    EXPECT_GT(g.anterior_nodes, 0);
    EXPECT_GT(g.posterior_nodes, 0);
    EXPECT_GE(g.ties, std::max(g.anterior_nodes, g.posterior_nodes));
    // Every grasped node within half the width of the site along the annulus, and within the
    // insertion of the free edge; the body's stretch of the line holds the position.
    const ValveModel& m = sc.model;
    std::set<int> grasped;
    double shortest_tie = 1e9;
    for (const SceneSpring& sp : sc.springs) {
      EXPECT_TRUE(sp.bilateral);
      // The ties hold the bands no closer than the contact law's reach (its alarm distance,
      // or the spacer): nearer, they would pull against the contact pushing the surfaces apart.
      EXPECT_GE(sp.rest_length, 0.5 * (o.model.al_thickness_mm + o.model.pl_thickness_mm) +
                                    std::max(d.spacer_mm, o.contact.alarm_mm) - 1e-12);
      shortest_tie = std::min(shortest_tie, sp.rest_length);
      grasped.insert(sp.a.front());
      grasped.insert(sp.b.front());
    }
    // ... and the nearest pairs are tied at about that distance, not farther.
    EXPECT_LT(shortest_tie, 0.5 * (o.model.al_thickness_mm + o.model.pl_thickness_mm) +
                                std::max(d.spacer_mm, o.contact.alarm_mm) + 0.5);
    EXPECT_EQ(static_cast<int>(grasped.size()), g.anterior_nodes + g.posterior_nodes);
    for (int i : grasped) {
      const bool anterior = m.surface_st(i, 0) < 0.5;
      const double t = m.surface_st(i, 1), depth = m.surface_plane(i, 1);
      EXPECT_LE(depth * (1.0 / t - 1.0),
                (anterior ? g.anterior_insertion_mm : g.posterior_insertion_mm) + 1e-9);
      const double x = anterior ? 2.0 * m.surface_st(i, 0) : 2.0 * (1.0 - m.surface_st(i, 0));
      EXPECT_NEAR(x, 0.5, 0.5 * d.width_mm / 35.0 * 2.0) << "within the width of the site";
    }
    EXPECT_LT(g.line_begin, 0.5);
    EXPECT_GT(g.line_end, 0.5);
  }
  // Wider arms grasp more tissue; a longer arm no less.
  const auto grasp = [&](const char* n) {
    return make_closure_scene(seq, p.truth->parameters, device_options(clip_device(n), 0.5))
        .grasps.front();
  };
  EXPECT_GT(grasp("NTW").anterior_nodes, grasp("NT").anterior_nodes);
  EXPECT_GE(grasp("XT").posterior_nodes, grasp("NT").posterior_nodes);
  // Impossible devices are refused by the options' check, naming the field.
  ClosureOptions bad = device_options(clip_device("XTW"), 0.5);
  bad.clips[0].arm_length_mm = 0;
  std::string why;
  EXPECT_FALSE(bad.is_valid(&why));
  EXPECT_NE(why.find("arm length"), std::string::npos);
}

TEST(DeviceClip, TheSettingRoundTripsWithItsDevice) {
  ClosureOptions o = device_options(clip_device("NTW"), 0.4);
  std::string text;
  for (const auto& [k, v] : describe_options(o))
    if (k == "clips") text = v;
  ClosureOptions back;
  apply_option("clips=" + text, &back);
  ASSERT_EQ(back.clips.size(), 1u);
  EXPECT_EQ(back.clips[0].device, "NTW");
  EXPECT_EQ(back.clips[0].width_mm, 6.0);
  EXPECT_EQ(back.clips[0].arm_length_mm, 9.0);
  EXPECT_DOUBLE_EQ(back.clips[0].anterior_s, 0.2);
  EXPECT_THROW(apply_option("clips=0.2,1,0.8,1,9.8,6", &back), Error) << "width without arm";
}

/// The XTW at the middle of the line on a small model (20 x 12): a clipped closure in about a
/// second.
ClosureOptions small_xtw_options() {
  ClosureOptions o = device_options(clip_device("XTW"), 0.5);
  o.model.ures = 20;
  o.model.vres = 12;
  return o;
}

TEST(DeviceClip, HoldsTheGraspedLeafletsTogetherThroughTheClosure) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "a closure takes minutes under AddressSanitizer; run in the -Werror build";
#endif
  const Patient p = make_virtual_patient(1);
  const ClosureOptions o = small_xtw_options();
  const ClosureResult r = simulate_closure(p.sequence, p.truth->parameters, o);
  ASSERT_TRUE(r.summary.converged()) << r.summary.reason;
  ASSERT_EQ(r.clip_grasps.size(), 1u);
  ASSERT_EQ(r.clip_gap_end_mm.size(), 1u);
  // The ties' atrial surface nodes (the facing pairs and their diagonal neighbours) stay within
  // 1 mm of the ties' mean rest length, after the grasp and at the end of systole: the bands are
  // held together, not merely pulled at one point.
  const ClosureScene sc = make_closure_scene(p.sequence, p.truth->parameters, o);
  double rest = 0;
  for (const SceneSpring& sp : sc.springs) rest += sp.rest_length;
  rest /= static_cast<double>(sc.springs.size());
  std::printf("tie rest %.3f mm, clipped %.3f mm, end %.3f mm\n", rest, r.clip_gap_clipped_mm[0],
              r.clip_gap_end_mm[0]);
  EXPECT_LT(r.clip_gap_clipped_mm[0], rest + 1.0);
  EXPECT_LT(r.clip_gap_end_mm[0], rest + 1.0);
  ASSERT_TRUE(r.orifice.has_value());
  // The device's stretch of the line is sealed: no opening lies inside it.
  const ClipGrasp& g = r.clip_grasps.front();
  for (const Opening& op : r.orifice->openings)
    EXPECT_TRUE(op.end <= g.line_begin + 1e-9 || op.begin >= g.line_end - 1e-9)
        << op.begin << "-" << op.end << " inside " << g.line_begin << "-" << g.line_end;
}

TEST(DeviceClip, AClipPhaseThatFailsIsRunAgainSlowerAndEndsWhereASlowerOneDoes) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "closures take minutes under AddressSanitizer; run in the -Werror build";
#endif
  // Arms 10 times stiffer than the device's closing in 0.05 s (5 steps of 0.01 s) drive a grasped
  // node through the other leaflet on virtual patient 1 at 20 x 12; in 0.1 s they do not (found
  // by a sweep of the phase's length, the arms' stiffness and dt: this case fails first).
  const Patient p = make_virtual_patient(1);
  ClosureOptions o = small_xtw_options();
  o.clips[0].stiffness_n_per_mm *= 10.0;
  o.clip_closing_s = 0.05;
  auto run = [&](double closing_s, int retries) {
    ClosureOptions q = o;
    q.clip_closing_s = closing_s;
    q.clip_phase_retries = retries;
    return simulate_closure(p.sequence, p.truth->parameters, q);
  };
  const ClosureResult once = run(0.05, 0);
  ASSERT_FALSE(once.summary.converged()) << "the scene no longer fails: choose another";
  EXPECT_NE(once.summary.reason.find("clip phase"), std::string::npos) << once.summary.reason;
  EXPECT_EQ(once.summary.clip_phase_retries, 0);

  const ClosureResult retried = run(0.05, kClipPhaseRetries);
  ASSERT_TRUE(retried.summary.converged()) << retried.summary.reason;
  EXPECT_EQ(retried.summary.clip_phase_retries, 1);
  EXPECT_DOUBLE_EQ(retried.summary.clip_phase_s, 0.1);
  // The retry is a run from end-diastole with the phase twice as long, to the bit ...
  const ClosureResult slower = run(0.1, 0);
  ASSERT_TRUE(slower.summary.converged()) << slower.summary.reason;
  EXPECT_EQ(slower.summary.clip_phase_retries, 0);
  EXPECT_DOUBLE_EQ(slower.summary.clip_phase_s, 0.1);
  EXPECT_EQ((retried.positions - slower.positions).cwiseAbs().maxCoeff(), 0.0);
  // ... and ends where the device's own 0.5 s phase does: how fast the arms close is not a
  // result.
  const ClosureResult standard = run(0.5, kClipPhaseRetries);
  ASSERT_TRUE(standard.summary.converged()) << standard.summary.reason;
  EXPECT_EQ(standard.summary.clip_phase_retries, 0);
  ASSERT_TRUE(retried.orifice && standard.orifice);
  std::printf("EROA after the retried 0.1 s phase %.2f mm^2, after 0.5 s %.2f mm^2\n",
              retried.orifice->eroa_mm2, standard.orifice->eroa_mm2);
  EXPECT_NEAR(retried.orifice->eroa_mm2, standard.orifice->eroa_mm2, 0.5);

  ClosureOptions bad = o;
  bad.clip_phase_retries = 5;
  std::string why;
  EXPECT_FALSE(bad.is_valid(&why));
  EXPECT_NE(why.find("clip_phase_retries"), std::string::npos) << why;
}

}  // namespace
}  // namespace mvtwin::forward
