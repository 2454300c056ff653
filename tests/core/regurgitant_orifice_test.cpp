#include "mvtwin/core/regurgitant_orifice.h"

#include <cmath>
#include <functional>
#include <limits>
#include <numbers>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "mvtwin/core/error.h"

namespace mvtwin {
namespace {

constexpr double kPi = std::numbers::pi;

/// A closed valve shaped like a slit between two plates, on the leaflet grid: the annulus an
/// ellipse in the plane z = 0 (the atrium is +z), each leaflet a plate sloping from its half of
/// the annulus down to depth `top_depth` at its free edge's top, then a wall `wall` mm deep
/// (0: no wall, the plates end edge to edge) along `wall_dir` (tilted about the slit's axis y by
/// `tilt` from straight down). The anterior plate is on -x, the posterior on +x; across the slit
/// (perpendicular to the walls) they are gap(y) apart, y along the slit; the commissures are the
/// slit's two ends, where both plates meet.
struct Slit {
  std::function<double(double)> gap;  // perpendicular gap at y, mm
  double half_length = 11.0;          // the slit runs over |y| <= half_length
  double wall = 0.0, tilt = 0.0, top_depth = 0.0;
  int ures = 160, vres = 30;

  LeafletGrid grid() const {
    const int U = ures, V = vres, half = U / 2;
    const double rx = 12.0, ry = half_length + 0.3, t0 = wall > 0 ? 0.7 : 1.0;
    const Eigen::Vector3d dir(std::sin(tilt), 0.0, -std::cos(tilt));
    LeafletGrid::Points p(static_cast<Eigen::Index>(U) * V, 3);
    for (int u = 0; u < U; ++u) {
      const bool anterior = u <= half;
      const int k = anterior ? u : U - u;  // position along the slit, 0..half
      const double phi = kPi * k / half;
      const double side = anterior ? -1.0 : 1.0;
      const Eigen::Vector3d a(side * rx * std::sin(phi), -ry * std::cos(phi), 0.0);
      const double y = -half_length + 2.0 * half_length * k / half;
      // Offset of each wall from the slit's mid-plane along x, so that the walls (parallel, along
      // dir) are gap(y) apart perpendicular to themselves.
      const double offset = 0.5 * gap(y) / std::cos(tilt);
      const Eigen::Vector3d top(side * offset, y, -top_depth);
      for (int v = 0; v < V; ++v) {
        const double t = static_cast<double>(v) / (V - 1);
        const Eigen::Vector3d q = t <= t0
                                      ? Eigen::Vector3d((1.0 - t / t0) * a + (t / t0) * top)
                                      : Eigen::Vector3d(top + (t - t0) / (1.0 - t0) * wall * dir);
        p.row(static_cast<Eigen::Index>(v) * U + u) = q.transpose();
      }
    }
    return LeafletGrid(U, V, std::move(p));
  }
};

/// A slit of width w over |y| <= 10 that narrows to nothing over the last mm to the commissures
/// (|y| = 11, where the plates meet).
std::function<double(double)> slot(double w) {
  return [w](double y) { return w * std::clamp(11.0 - std::abs(y), 0.0, 1.0); };
}

/// Its open area for a seal distance: w x 20 mm, and in each 1 mm taper, where the leaflets' edges
/// form a V of half-angle theta (tan theta = w / 2 per mm), the part whose gap across the V
/// (w(y) cos theta) is above the seal: the integral of w(y) dy there.
double open_area_of_slot(double w, double seal) {
  const double cos2 = 1.0 / (1.0 + 0.25 * w * w);
  const double w_seal = seal / std::sqrt(cos2);  // width where the gap across reaches the seal
  return w > w_seal ? 20.0 * w + 2.0 * (w * w - w_seal * w_seal) / (2.0 * w) : 0.0;
}

TEST(RegurgitantOrifice, CoplanarPlatesSlotsOfOneAndSixTenthsMm) {
  for (double w : {1.0, 0.6}) {
    Slit s;
    s.gap = slot(w);
    const RegurgitantOrifice r = measure_regurgitant_orifice(s.grid(), {});
    const double expected = open_area_of_slot(w, 0.3);
    EXPECT_NEAR(r.aroa_mm2, expected, 0.02 * expected) << "slot " << w << " mm";
    ASSERT_EQ(r.openings.size(), 1u);
    EXPECT_NEAR(r.openings[0].max_gap_mm, w, 1e-6);
    // It begins in the taper, within 1 mm of the commissure (of 22 mm).
    EXPECT_GT(r.openings[0].begin, 0.0);
    EXPECT_LT(r.openings[0].begin, 1.0 / 22.0);
    EXPECT_NEAR(r.openings[0].end, 1.0 - r.openings[0].begin, 1e-9);
    EXPECT_NEAR(r.eroa_mm2, 0.611 * r.aroa_mm2, 1e-12);
  }
}

TEST(RegurgitantOrifice, WallsTwoMmDeepFacingAcrossTheSlit) {
  for (double w : {1.0, 0.6}) {
    Slit s;
    s.gap = slot(w);
    s.wall = 2.0;
    s.top_depth = 4.0;
    const RegurgitantOrifice r = measure_regurgitant_orifice(s.grid(), {});
    const double expected = open_area_of_slot(w, 0.3);
    EXPECT_NEAR(r.aroa_mm2, expected, 0.02 * expected) << "walls " << w << " mm apart";
  }
}

TEST(RegurgitantOrifice, SlotTiltedSixtyDegreesFromTheAnnulusNormal) {
  // Walls tilted 60 degrees from the annulus normal: along the normal they overlap (a line of
  // sight from the atrium sees little of the slit), across they are still w apart.
  for (double w : {1.0, 0.6}) {
    Slit s;
    s.gap = slot(w);
    s.wall = 2.0;
    s.top_depth = 4.0;
    s.tilt = kPi / 3.0;
    const RegurgitantOrifice r = measure_regurgitant_orifice(s.grid(), {});
    const double expected = open_area_of_slot(w, 0.3);
    EXPECT_NEAR(r.aroa_mm2, expected, 0.02 * expected) << "tilted walls " << w << " mm apart";
  }
}

TEST(RegurgitantOrifice, PlatesWithinTheSealDistanceAreClosed) {
  for (double w : {0.0, 0.1, 0.25, 0.299}) {
    Slit s;
    s.gap = slot(w);
    s.wall = 2.0;
    s.top_depth = 4.0;
    const RegurgitantOrifice r = measure_regurgitant_orifice(s.grid(), {});
    EXPECT_EQ(r.aroa_mm2, 0.0) << w;
    EXPECT_TRUE(r.openings.empty());
    EXPECT_EQ(r.grade, MrGrade::kNone);
  }
  // The seal is the option's: the same 0.25 mm slit is open below a 0.2 mm seal.
  Slit s;
  s.gap = slot(0.25);
  OrificeOptions o;
  o.seal_mm = 0.2;
  EXPECT_NEAR(measure_regurgitant_orifice(s.grid(), o).aroa_mm2, open_area_of_slot(0.25, 0.2),
              0.02 * open_area_of_slot(0.25, 0.2));
}

TEST(RegurgitantOrifice, AClipMakesTwoOpenings) {
  // A slit 1 mm wide sealed (0.1 mm apart) over 2 mm around y = 2 (a clip): two openings, 11 and
  // 7 mm long.
  Slit s;
  s.gap = [](double y) {
    const double w = slot(1.0)(y);
    return std::abs(y - 2.0) <= 1.0 ? 0.1 : w;
  };
  s.ures = 320;
  const RegurgitantOrifice r = measure_regurgitant_orifice(s.grid(), {});
  ASSERT_EQ(r.openings.size(), 2u);
  // Each: the full-width part and the taper at its commissure; the step at the clip falls
  // between two columns (0.14 mm apart here).
  const double taper = 0.5 * (open_area_of_slot(1.0, 0.3) - 20.0);
  EXPECT_NEAR(r.openings[0].area_mm2, 11.0 + taper, 0.02 * 11.0);
  EXPECT_NEAR(r.openings[1].area_mm2, 7.0 + taper, 0.02 * 7.0);
  EXPECT_LT(r.openings[0].end, r.openings[1].begin);  // the larger is the first along y
}

TEST(RegurgitantOrifice, ADevicesStretchIsCutOutOfTheOpeningsExactly) {
  // A slit 1 mm wide, and a device filling [b0, b1] of the line whose edges fall between the
  // columns of a coarse grid (0.55 mm apart): two openings, ending and beginning exactly at the
  // device's edges, their area the slit's less the device's 22 (b1 - b0) mm x 1 mm.
  Slit s;
  s.gap = slot(1.0);
  s.ures = 80;
  const double b0 = 0.4321, b1 = 0.5678;
  const RegurgitantOrifice open = measure_regurgitant_orifice(s.grid(), {});
  OrificeOptions o;
  o.blocked = {{b0, b1}};
  const RegurgitantOrifice r = measure_regurgitant_orifice(s.grid(), o);
  ASSERT_EQ(r.openings.size(), 2u);
  const Opening& left = r.openings[0].begin < r.openings[1].begin ? r.openings[0] : r.openings[1];
  const Opening& right = &left == &r.openings[0] ? r.openings[1] : r.openings[0];
  EXPECT_NEAR(left.end, b0, 1e-12);
  EXPECT_NEAR(right.begin, b1, 1e-12);
  EXPECT_NEAR(r.aroa_mm2, open.aroa_mm2 - 22.0 * (b1 - b0) * 1.0, 1e-6);
  // A device narrower than the column spacing, between two columns, still splits the slit.
  o.blocked = {{0.5001, 0.5002}};
  const RegurgitantOrifice thin = measure_regurgitant_orifice(s.grid(), o);
  EXPECT_EQ(thin.openings.size(), 2u);
  EXPECT_NEAR(thin.aroa_mm2, open.aroa_mm2 - 22.0 * 0.0001, 1e-6);
}

TEST(RegurgitantOrifice, IndependentOfPoseAndConvergentUnderRefinement) {
  Slit s;
  s.gap = slot(0.8);
  s.wall = 2.0;
  s.top_depth = 3.0;
  const LeafletGrid g = s.grid();
  const RegurgitantOrifice r0 = measure_regurgitant_orifice(g, {});
  // A rigid motion of the whole valve.
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  LeafletGrid moved = g;
  for (Eigen::Index i = 0; i < moved.points().rows(); ++i)
    moved.points().row(i) =
        (R * g.points().row(i).transpose() + Eigen::Vector3d(5, -7, 40)).transpose();
  EXPECT_NEAR(measure_regurgitant_orifice(moved, {}).aroa_mm2, r0.aroa_mm2, 1e-9 * r0.aroa_mm2);
  // Coarser columns converge towards the fine answer.
  double previous_error = 1e300;
  for (int U : {40, 80, 160}) {
    s.ures = U;
    const double e =
        std::abs(measure_regurgitant_orifice(s.grid(), {}).aroa_mm2 - open_area_of_slot(0.8, 0.3));
    EXPECT_LT(e, previous_error + 1e-12) << U;
    previous_error = e;
  }
}

TEST(RegurgitantOrifice, CoaptationLengthAndDepthOfSealedWalls) {
  // Walls 3 mm deep whose tops are 5 mm below the annulus plane, 0.2 mm apart: the leaflets
  // appose over the walls (3 mm) plus the bit of each sloping plate within the seal of the
  // other wall's top; the apposition starts at the walls' top.
  Slit s;
  s.gap = slot(0.2);
  s.wall = 3.0;
  s.top_depth = 5.0;
  s.vres = 60;
  const RegurgitantOrifice r = measure_regurgitant_orifice(s.grid(), {});
  EXPECT_EQ(r.aroa_mm2, 0.0);
  EXPECT_NEAR(r.coapting_fraction, 1.0, 1e-12);
  EXPECT_NEAR(r.coaptation_length_mm, 3.0, 0.15);
  EXPECT_NEAR(r.coaptation_depth_mm, 5.0, 0.1);
}

TEST(RegurgitantOrifice, GradesFollowAse2017) {
  EXPECT_EQ(mr_grade_of(0.0), MrGrade::kNone);
  EXPECT_EQ(mr_grade_of(0.99), MrGrade::kNone);
  EXPECT_EQ(mr_grade_of(1.0), MrGrade::kMild);
  EXPECT_EQ(mr_grade_of(19.9), MrGrade::kMild);
  EXPECT_EQ(mr_grade_of(20.0), MrGrade::kModerate);
  EXPECT_EQ(mr_grade_of(39.9), MrGrade::kModerate);
  EXPECT_EQ(mr_grade_of(40.0), MrGrade::kSevere);
  EXPECT_EQ(mr_grade_name(MrGrade::kSevere), "severe");
}

TEST(RegurgitantOrifice, RefusesBadInput) {
  Slit s;
  s.gap = slot(1.0);
  LeafletGrid g = s.grid();
  OrificeOptions o;
  o.seal_mm = -1;
  EXPECT_THROW(measure_regurgitant_orifice(g, o), Error);
  o = {};
  o.contraction_coefficient = 0;
  EXPECT_THROW(measure_regurgitant_orifice(g, o), Error);
  g.points()(5, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(measure_regurgitant_orifice(g, {}), Error);
}

}  // namespace
}  // namespace mvtwin
