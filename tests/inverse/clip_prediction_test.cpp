#include "mvtwin/inverse/clip_prediction.h"

#include <gtest/gtest.h>

#include "mvtwin/core/error.h"
#include "mvtwin/core/virtual_patient.h"

namespace mvtwin::inverse {
namespace {

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
  forward::ClosureOptions o;
  o.model.ures = 16;
  o.model.vres = 8;
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
  forward::ClosureOptions o;
  o.model.ures = 16;
  o.model.vres = 8;
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

}  // namespace
}  // namespace mvtwin::inverse
