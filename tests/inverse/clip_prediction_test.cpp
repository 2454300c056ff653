#include "mvtwin/inverse/clip_prediction.h"

#include <cstdio>

#include <gtest/gtest.h>

#include "mvtwin/core/error.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/inverse/parameter_space.h"

namespace mvtwin::inverse {
namespace {

/// A coarse closure (16 x 8) for the tests that simulate several.
forward::ClosureOptions coarse_options() {
  forward::ClosureOptions o;
  o.model.ures = 16;
  o.model.vres = 8;
  return o;
}

TEST(ClipSites, ParsedAndMappedOntoBothLeaflets) {
  const std::vector<ClipSite> s = parse_clip_sites("0.5,1; 0.3");
  ASSERT_EQ(s.size(), 2u);
  EXPECT_DOUBLE_EQ(s[1].position, 0.3);
  EXPECT_DOUBLE_EQ(s[1].depth, 1.0);
  const forward::ClipOptions c = clip_options(s[0]);
  EXPECT_DOUBLE_EQ(c.anterior_s, 0.25) << "the middle of the anterior leaflet";
  EXPECT_DOUBLE_EQ(c.posterior_s, 0.75) << "... facing the middle of the posterior one";
  const forward::ClipOptions d = clip_options({0.2, 0.8});
  EXPECT_DOUBLE_EQ(d.anterior_s, 0.1);
  EXPECT_DOUBLE_EQ(d.posterior_s, 0.9)
      << "both sites the same way from the anterolateral commissure";
  EXPECT_DOUBLE_EQ(d.anterior_t, 0.8);
  for (const char* bad : {"", "0.5,x", "1.2,1", "0,1", "0.5,0.1", "0.5 1"})
    EXPECT_THROW(parse_clip_sites(bad), Error) << bad;
}

TEST(ClipSites, CandidatesAndRanking) {
  EXPECT_EQ(clip_candidates(false).size(), 7u);
  const auto pairs = clip_candidates(true);
  EXPECT_EQ(pairs.size(), 7u + 15u);  // pairs of 0.2..0.8 at least 0.2 apart
  for (const auto& c : pairs)
    if (c.size() == 2) {
      EXPECT_GE(c[1].position - c[0].position, 0.2 - 1e-9);
    }
  std::vector<ClipScenario> s(3);
  const double area[3] = {30.0, 0.0, 5.0};
  for (int i = 0; i < 3; ++i) {
    s[i].quality.converged = i != 1;
    s[i].quality.orifice.eroa_mm2 = area[i];
  }
  rank_by_residual_orifice(&s);
  EXPECT_DOUBLE_EQ(s[0].quality.orifice.eroa_mm2, 5.0);
  EXPECT_FALSE(s[2].quality.converged) << "a failed simulation ranks last, whatever its area";
}

TEST(ClipPrediction, ClippedSitesEndTogetherAndTheNoClipRunIsReported) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "closures take too long under AddressSanitizer";
#endif
  const Patient p = make_virtual_patient(1);
  const forward::ClosureOptions o = coarse_options();
  const auto r = simulate_clips(p, p.truth->parameters, o, {{}, {ClipSite{0.5, 1.0}}}, 2);
  ASSERT_EQ(r.size(), 2u);
  ASSERT_TRUE(r[0].quality.converged) << r[0].quality.reason;
  ASSERT_TRUE(r[1].quality.converged) << r[1].quality.reason;
  EXPECT_TRUE(r[0].quality.clip_gap_mm.empty());
  ASSERT_EQ(r[1].quality.clip_gap_mm.size(), 1u);
  EXPECT_LT(r[1].quality.clip_gap_mm[0], 2.0) << "the clipped sites stay within the clip's grasp";
  EXPECT_GT(r[0].quality.orifice.coapting_fraction, 0.5) << "the valve closes";
}

// Candidates two at a time against one at a time: the same closures bit for bit (scripts/tsan
// runs this under ThreadSanitizer).
TEST(ClipPrediction, ConcurrentCandidatesEqualSequentialOnes) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "closures take too long under AddressSanitizer";
#endif
  const Patient p = make_virtual_patient(2);
  const forward::ClosureOptions o = coarse_options();
  const std::vector<std::vector<ClipSite>> sites = {
      {}, {ClipSite{0.5, 1.0}}, {ClipSite{0.3, 1.0}}, {ClipSite{0.3, 1.0}, ClipSite{0.7, 1.0}}};
  const auto two = simulate_clips(p, p.truth->parameters, o, sites, 2);
  const auto one = simulate_clips(p, p.truth->parameters, o, sites, 1);
  ASSERT_EQ(two.size(), sites.size());
  ASSERT_EQ(one.size(), sites.size());
  for (size_t i = 0; i < sites.size(); ++i) {
    const ClosureQuality &a = two[i].quality, &b = one[i].quality;
    EXPECT_EQ(a.converged, b.converged) << i;
    EXPECT_EQ(a.reason, b.reason) << i;
    EXPECT_EQ(a.orifice.aroa_mm2, b.orifice.aroa_mm2) << i;
    EXPECT_EQ(a.orifice.coapting_fraction, b.orifice.coapting_fraction) << i;
    EXPECT_EQ(a.clip_gap_mm, b.clip_gap_mm) << i;
  }
  EXPECT_TRUE(two[1].quality.converged) << two[1].quality.reason;
}

// NT and XT differ only in their arms' length (9 and 12 mm), which caps how deep a leaflet
// inserts: where both hold all of it they grasp the same bands, and the valve is simulated once
// for both (the plan's 42 single clips hold 14 such pairs on cohort seed 2026's patient 2); where
// a leaflet inserts deeper than the shorter arm, they are two valves.
TEST(ClipPrediction, DevicesThatGraspAlikeAreSimulatedOnceAndOthersApart) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "closures take too long under AddressSanitizer";
#endif
  const Patient p = make_virtual_patient(1);
  forward::ClosureOptions o;
  o.model.ures = 20;
  o.model.vres = 12;
  const std::vector<std::vector<ClipSite>> sites = {{ClipSite{0.5, 1.0, "NT"}},
                                                    {ClipSite{0.5, 1.0, "XT"}},
                                                    {ClipSite{0.5, 1.0, "NT", 11.0}},
                                                    {ClipSite{0.5, 1.0, "XT", 11.0}}};
  EXPECT_EQ(alike_clips(p.sequence, sites), (std::vector<size_t>{0, 0, 2, 3}));
  // The valve without a clip, a spring and a device are three valves.
  EXPECT_EQ(alike_clips(p.sequence, {{}, {ClipSite{0.5, 1.0}}, {ClipSite{0.5, 1.0, "NT"}}, {}}),
            (std::vector<size_t>{0, 1, 2, 0}));
  std::vector<ClipScenario> s = simulate_clips(p, p.truth->parameters, o, sites, 2);
  open_clips(p, p.truth->parameters, o, forward::DiastoleOptions{}, sites.size(), 2, &s);
  for (const ClipScenario& c : s) {
    ASSERT_TRUE(c.quality.converged) << c.quality.reason;
    ASSERT_EQ(c.quality.clip_grasps.size(), 1u);
    ASSERT_TRUE(c.opening.converged) << c.opening.reason;
  }
  // The leaflets insert less than either arm: one valve, each scenario with its own device.
  const forward::ClipGrasp &nt = s[0].quality.clip_grasps[0], &xt = s[1].quality.clip_grasps[0];
  ASSERT_LT(nt.anterior_insertion_mm, 9.0);
  ASSERT_LT(nt.posterior_insertion_mm, 9.0);
  EXPECT_EQ(nt.device, "NT");
  EXPECT_EQ(xt.device, "XT");
  EXPECT_EQ(s[0].sites[0].device, "NT");
  EXPECT_EQ(s[1].sites[0].device, "XT");
  EXPECT_EQ(s[0].quality.orifice.aroa_mm2, s[1].quality.orifice.aroa_mm2);
  EXPECT_EQ(s[0].quality.clip_gap_mm, s[1].quality.clip_gap_mm);
  EXPECT_EQ(s[0].opening.mva_cm2, s[1].opening.mva_cm2);
  // 11 mm of tissue: the NT's arm holds 9 of it, the XT's all; two valves.
  const forward::ClipGrasp &nt11 = s[2].quality.clip_grasps[0], &xt11 = s[3].quality.clip_grasps[0];
  EXPECT_DOUBLE_EQ(nt11.anterior_insertion_mm, 9.0);
  EXPECT_DOUBLE_EQ(xt11.anterior_insertion_mm, 11.0);
  EXPECT_GT(xt11.anterior_nodes, nt11.anterior_nodes);
  EXPECT_NE(s[2].quality.clip_gap_mm, s[3].quality.clip_gap_mm);
  std::printf("alike: AROA %.3f / %.3f mm^2; 11 mm inserted: %.3f / %.3f mm^2\n",
              s[0].quality.orifice.aroa_mm2, s[1].quality.orifice.aroa_mm2,
              s[2].quality.orifice.aroa_mm2, s[3].quality.orifice.aroa_mm2);
}

TEST(MeshCheck, RefinedMeshIsFinerByTheFactorAndEven) {
  forward::ClosureOptions o;
  o.model.ures = 30;
  o.model.vres = 30;
  EXPECT_EQ(refined_options(o, 4.0 / 3.0).model.ures, 40);
  EXPECT_EQ(refined_options(o, 4.0 / 3.0).model.vres, 40);
  o.model.ures = 16;
  o.model.vres = 8;
  const forward::ClosureOptions r = refined_options(o, 4.0 / 3.0);
  EXPECT_EQ(r.model.ures, 22);  // 21.3 rounded up to even
  EXPECT_EQ(r.model.vres, 12);  // 10.7 -> 11 -> 12
  EXPECT_EQ(r.dt, o.dt);        // only the mesh changes
  EXPECT_EQ(refined_options(o, 1.0).model.ures, 16);
  EXPECT_THROW(refined_options(o, 0.5), Error);
  EXPECT_THROW(refined_options(o, std::nan("")), Error);
}

// The interval of an outcome: the posterior's spread and the mesh's change, each recomputed
// here from its own simulations (the sigma point's and the refined mesh's).
TEST(ClipPrediction, IntervalsAddTheMeshsChangeToTheParametersSpread) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "closures take too long under AddressSanitizer";
#endif
  const Patient p = make_virtual_patient(1);
  const forward::ClosureOptions o = coarse_options();
  const ParameterSpace space("peak_pressure", p.truth->parameters);
  CalibrationRecord rec;
  rec.names = {space.specs()[0].name};
  rec.parameters = p.truth->parameters;
  rec.covariance = Eigen::MatrixXd::Constant(1, 1, 4.0);  // 2 mmHg SD
  rec.sd = Eigen::VectorXd::Constant(1, 2.0);
  const CalibrationPosterior post = posterior_of(rec);
  ASSERT_TRUE(post.usable) << post.why_not;
  forward::DiastoleOptions diastole;
  std::vector<ClipScenario> s = simulate_clips(p, post.apply(post.fitted), o, {{}}, 1);
  ASSERT_TRUE(s[0].quality.converged) << s[0].quality.reason;
  const ClosureQuality before = s[0].quality;
  const SigmaPoints sp = propagate_clip_uncertainty(p, post, o, diastole, before, 1, 2, &s);
  ASSERT_EQ(sp.points.size(), 1u);
  const ClipUncertainty& u = s[0].uncertainty;
  ASSERT_TRUE(u.computed);
  // The parameters' part: the secant over one SD.
  const auto at_point = simulate_clips(p, post.apply(sp.points[0]), o, {{}}, 1);
  ASSERT_TRUE(at_point[0].quality.converged);
  const double eroa = before.orifice.eroa_mm2;
  EXPECT_NEAR(u.sd_parameters[0],
              std::abs(at_point[0].quality.orifice.eroa_mm2 - eroa) / std::abs(sp.scale[0]), 1e-9);
  // The mesh's part: the same valve on the 22 x 12 mesh.
  const auto fine =
      simulate_clips(p, post.apply(post.fitted), refined_options(o, 4.0 / 3.0), {{}}, 1);
  ASSERT_TRUE(fine[0].quality.converged);
  EXPECT_NEAR(u.at_refined[0], fine[0].quality.orifice.eroa_mm2, 1e-9);
  EXPECT_NEAR(u.sd_mesh[0], std::abs(fine[0].quality.orifice.eroa_mm2 - eroa), 1e-9);
  EXPECT_NEAR(u.sd[0], std::hypot(u.sd_parameters[0], u.sd_mesh[0]), 1e-9);
  // Without the check the interval is the parameters' alone.
  std::vector<ClipScenario> t = simulate_clips(p, post.apply(post.fitted), o, {{}}, 1);
  propagate_clip_uncertainty(p, post, o, diastole, before, 1, 2, &t, MeshCheck{false, 1.0});
  EXPECT_EQ(t[0].uncertainty.sd_mesh[0], 0.0);
  EXPECT_NEAR(t[0].uncertainty.sd[0], u.sd_parameters[0], 1e-9);
}

// Two options tie when their EROAs differ by less than 1.96 SD of the difference; the mesh's
// part is how much the refined mesh moves the difference, not either EROA.
TEST(ClipPrediction, ATieCountsTheMeshsChangeOfTheDifference) {
  auto option = [](double eroa, double refined) {
    ClipScenario s;
    s.quality.converged = true;
    s.quality.orifice.eroa_mm2 = eroa;
    ClipUncertainty& u = s.uncertainty;
    u.computed = true;
    u.at_points.resize(0, kClipOutcomes);  // no sigma points: the parameters add nothing
    u.sd_parameters = Eigen::VectorXd::Zero(kClipOutcomes);
    u.at_refined = Eigen::VectorXd::Constant(kClipOutcomes, refined);
    u.sd_mesh = Eigen::VectorXd::Constant(kClipOutcomes, std::abs(refined - eroa));
    u.sd = u.sd_mesh;
    return s;
  };
  const SigmaPoints none;
  // 10 against 12, both 3 lower on the finer mesh: the difference does not move, no tie
  // (each EROA's own interval, +-5.9, would overlap the other's).
  EXPECT_FALSE(indistinguishable(none, option(10, 7), option(12, 9)));
  // The finer mesh turns the difference around (10 vs 12 -> 10 vs 10): SD 2, a tie.
  EXPECT_TRUE(indistinguishable(none, option(10, 10), option(12, 10)));
  // A difference of 5 with the mesh moving it by 2: beyond 1.96 x 2.
  EXPECT_FALSE(indistinguishable(none, option(10, 10), option(15, 13)));
  // A failed refined run (NaN): no tie is claimed.
  EXPECT_FALSE(indistinguishable(none, option(10, std::nan("")), option(12, 10)));
}

}  // namespace
}  // namespace mvtwin::inverse
