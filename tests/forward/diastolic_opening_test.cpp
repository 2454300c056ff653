#include "mvtwin/forward/diastolic_opening.h"

#include <cmath>

#include <gtest/gtest.h>

#include "mvtwin/core/closure_measures.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/units.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/forward/clip_device.h"

namespace mvtwin::forward {
namespace {

/// The area of a triangle mesh seen along the unit normal n.
double projected_area(const TriangleMesh& m, const Eigen::Vector3d& n) {
  double area = 0;
  for (Eigen::Index t = 0; t < m.F.rows(); ++t) {
    const Eigen::Vector3d a = m.V.row(m.F(t, 0)), b = m.V.row(m.F(t, 1)), c = m.V.row(m.F(t, 2));
    area += 0.5 * std::abs((b - a).cross(c - a).dot(n));
  }
  return area;
}

TEST(Gorlin, MeanGradientInvertsTheGorlinRelation) {
  // MVA = Q / (37.7 sqrt(dP)): 37.7 mL/s through 1 cm^2 is 1 mmHg, and the gradient grows with
  // the square of the flow and falls with the square of the area.
  EXPECT_NEAR(gorlin_mean_gradient_mmhg(37.7, 1.0), 1.0, 1e-12);
  EXPECT_NEAR(gorlin_mean_gradient_mmhg(2 * 37.7, 1.0), 4.0, 1e-12);
  EXPECT_NEAR(gorlin_mean_gradient_mmhg(37.7, 2.0), 0.25, 1e-12);
  // 70 mL over 0.5 s through 1.5 cm^2: the stenosis thresholds meet near there.
  const double g = gorlin_mean_gradient_mmhg(140.0, 1.5);
  EXPECT_NEAR(g, std::pow(140.0 / (37.7 * 1.5), 2), 1e-12);
  EXPECT_GT(g, 5.0);
  EXPECT_TRUE(std::isinf(gorlin_mean_gradient_mmhg(140.0, 0.0)));
}

TEST(Diastole, RefusesImpossibleOptions) {
  DiastoleOptions d;
  d.transmitral_mmhg = -1;
  std::string why;
  EXPECT_FALSE(d.is_valid(&why));
  EXPECT_NE(why.find("transmitral"), std::string::npos);
  const Patient p = make_virtual_patient(1);
  EXPECT_THROW(simulate_diastole(p.sequence, p.truth->parameters, {}, d), Error);
}

TEST(Diastole, TheOpenValveRestsOnItsWidestFrameAndAClipMakesTwoSmallerOrifices) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "two simulations take minutes under AddressSanitizer";
#endif
  const Patient p = make_virtual_patient(1);
  ClosureOptions o;
  // 30 x 12: with a contact as soft as diastole's pressure the clip phase crossed here, in the
  // closed posteromedial commissure's fold, and the clipped valve did not open (it opened from
  // 30 x 13 on, the finest depth step the mesher makes at ures 30).
  o.model.ures = 30;
  o.model.vres = 12;
  const DiastolicOpening open = simulate_diastole(p.sequence, p.truth->parameters, o);
  ASSERT_TRUE(open.converged) << open.reason;
  // The widest frame up to end-diastole (a virtual patient's early diastole, frame 0).
  double widest = 0;
  int frame = -1;
  for (int f = 0; f <= p.sequence.end_diastole; ++f) {
    const double a = measure_closure(p.sequence.frames[static_cast<size_t>(f)]).orifice_area_mm2;
    if (a > widest) {
      widest = a;
      frame = f;
    }
  }
  EXPECT_EQ(open.frame, frame);
  // Held open by the transmitral pressure, the valve opens at least as wide as the frame shows
  // (within the coarser model's sampling), and it is one opening: no stenosis.
  EXPECT_GT(open.mva_cm2, 0.9 * units::mm2_to_cm2(widest));
  ASSERT_EQ(open.openings_cm2.size(), 1u);
  EXPECT_FALSE(open.stenosis);
  EXPECT_NEAR(open.gradient_mmhg, gorlin_mean_gradient_mmhg(140.0, open.mva_cm2), 1e-12);

  // A device in the middle of the line: a double orifice, smaller in all.
  const ClipDevice& d = clip_device("XTW");
  ClipOptions c;
  c.anterior_s = 0.25;
  c.posterior_s = 0.75;
  c.width_mm = d.width_mm;
  c.arm_length_mm = d.arm_length_mm;
  c.device = d.name;
  o.clips.push_back(c);
  const DiastolicOpening clipped = simulate_diastole(p.sequence, p.truth->parameters, o);
  ASSERT_TRUE(clipped.converged) << clipped.reason;
  // The grasp holds on the widest frame itself (with the diastole's contact as soft as its 5
  // mmHg, an anterior free edge beside the grasp went through the posterior leaflet and the
  // opening fell back to end-diastole, or failed).
  EXPECT_EQ(clipped.frame, frame) << clipped.fallback;
  EXPECT_TRUE(clipped.fallback.empty()) << clipped.fallback;
  EXPECT_EQ(clipped.openings_cm2.size(), 2u);
  EXPECT_LT(clipped.mva_cm2, 0.8 * open.mva_cm2);
  EXPECT_GT(clipped.gradient_mmhg, open.gradient_mmhg);
  // The device and the tissue it holds close what they cover. The XTW holds the leaflets
  // against each other, so its footprint lies on tissue; the PASCAL Ace holds them around a
  // 6 mm spacer, so between its bands the leaflets alone would leave a channel that the device
  // fills: the openings between the leaflets alone are larger by no more than the footprint seen
  // along the annulus normal.
  const ClipDevice& ace = clip_device("ACE");
  ClosureOptions oa = o;
  oa.clips[0].width_mm = ace.width_mm;
  oa.clips[0].arm_length_mm = ace.arm_length_mm;
  oa.clips[0].spacer_mm = ace.spacer_mm;
  oa.clips[0].device = ace.name;
  const DiastolicOpening spaced = simulate_diastole(p.sequence, p.truth->parameters, oa);
  ASSERT_TRUE(spaced.converged) << spaced.reason;
  const ClosureSample& last = spaced.result.samples.back();
  const auto annulus = last.la_surface.points().topRows(last.la_surface.ures());
  const AnnulusPlane plane = least_squares_plane(annulus);
  const double bare_cm2 = units::mm2_to_cm2(
      measure_closure(annulus, last.la_surface.triangulate(), 0.2).orifice_area_mm2);
  const TriangleMesh f = clip_device_footprint(spaced.result, plane);
  ASSERT_GT(f.F.rows(), 0);
  const double footprint_mm2 = projected_area(f, plane.normal);
  EXPECT_GT(bare_cm2, spaced.mva_cm2) << "the device fills the channel between its bands";
  // (0.2 mm pixels along the footprint's outline: 0.2 x its perimeter, under 0.1 cm^2 here)
  EXPECT_LE(bare_cm2 - spaced.mva_cm2, units::mm2_to_cm2(footprint_mm2) + 0.1)
      << "footprint " << footprint_mm2 << " mm^2";
}

TEST(Diastole, AClipsFootprintIsTheHullOfItsGraspedBandsSeenAlongTheAnnulusNormal) {
  // Two bands of grasped nodes at different heights, the device between them: anterior nodes on
  // y = 2, posterior on y = -1.5, spread over x in [-3, 3] (a 6 mm device), with interior points.
  // Seen along a tilted annulus normal the footprint is the hull of their projections.
  ClosureResult r;
  std::vector<Eigen::Vector3d> p;
  ClipGrasp g;
  for (int k = 0; k <= 6; ++k) {
    g.anterior_band.push_back(static_cast<int>(p.size()));
    p.emplace_back(-3.0 + k, 2.0, 0.3 * k);
    g.posterior_band.push_back(static_cast<int>(p.size()));
    p.emplace_back(-3.0 + k, -1.5, -0.2 * k);
    g.posterior_band.push_back(static_cast<int>(p.size()));
    p.emplace_back(-3.0 + k, 0.5, 1.0);  // inside the hull
  }
  r.positions.resize(3 * static_cast<Eigen::Index>(p.size()));
  for (size_t i = 0; i < p.size(); ++i)
    r.positions.segment<3>(3 * static_cast<Eigen::Index>(i)) = p[i];
  r.clip_grasps.push_back(g);
  r.clip_grasps.push_back(ClipGrasp{});  // the paper's spring: no band, no footprint
  const double tilt = 0.4;
  AnnulusPlane plane{Eigen::Vector3d::Zero(), Eigen::Vector3d(0.0, std::sin(tilt), std::cos(tilt))};
  const TriangleMesh f = clip_device_footprint(r, plane);
  ASSERT_EQ(f.V.rows(), 4);  // the four corners; the points on the edges and inside drop out
  ASSERT_EQ(f.F.rows(), 2);
  // Projected area against the analytic one: in the plane the device's band is 6 mm along x,
  // and across it 3.5 cos(tilt) at x = -3 and 3.5 cos(tilt) - (1.8 + 1.2) sin(tilt) at x = 3
  // (the anterior band rises, the posterior sinks): a trapezoid.
  EXPECT_NEAR(projected_area(f, plane.normal), 6.0 * (3.5 * std::cos(tilt) - 1.5 * std::sin(tilt)),
              1e-9);
  // No bands at all: nothing is covered.
  ClosureResult none;
  none.clip_grasps.push_back(ClipGrasp{});
  EXPECT_EQ(clip_device_footprint(none, plane).F.rows(), 0);
}

}  // namespace
}  // namespace mvtwin::forward
