#include "mvtwin/detection/tee_renderer.h"

#include <cmath>

#include <gtest/gtest.h>
#include <Eigen/LU>

#include "mvtwin/core/error.h"
#include "mvtwin/core/triangle_bvh.h"
#include "mvtwin/core/virtual_patient.h"

namespace mvtwin::detection {
namespace {

TeeRenderOptions small() {
  TeeRenderOptions o;
  o.voxel_mm = 1.5;
  o.box_mm = 66;
  o.seed = 5;
  return o;
}

/// Mean grey level of the voxels within `near` mm of the frame's leaflet surface, and of the
/// voxels inside the sector between 6 and 12 mm from it (blood on either side, mostly).
std::pair<double, double> leaflet_and_surroundings(const ImageVolume& im, const ValveFrame& f) {
  const TriangleBvh bvh(f.la_surface->triangulate());
  double a = 0, b = 0;
  int na = 0, nb = 0;
  for (int k = 0; k < im.size[2]; ++k)
    for (int j = 0; j < im.size[1]; ++j)
      for (int i = 0; i < im.size[0]; ++i) {
        const double v = im.at(i, j, k);
        if (v <= 0.0) continue;  // outside the sector
        const double d = bvh.closest(im.position(i, j, k)).distance;
        if (d < 0.6) {
          a += v;
          ++na;
        } else if (d > 6 && d < 12) {
          b += v;
          ++nb;
        }
      }
  return {na ? a / na : 0.0, nb ? b / nb : 0.0};
}

TEST(TeeRenderer, LeafletsAreBrightOnDarkBloodAndTheGeometryIsTheProbes) {
  const Patient p = make_virtual_patient(3);
  const int ed = p.sequence.end_diastole;
  const TeeRenderOptions o = small();
  const TeeGeometry g = tee_geometry(p.sequence, o);
  // The probe sits on the atrial side, about probe_depth_mm from the annulus, looking at it.
  const Eigen::Vector3d c = p.sequence.frames[ed].annulus.colwise().mean().transpose();
  EXPECT_NEAR((g.apex - c).norm(), o.probe_depth_mm, 1e-9);
  EXPECT_NEAR(g.axes.determinant(), 1.0, 1e-9);
  EXPECT_LT((g.axes.col(2) - (c - g.apex).normalized()).norm(), 1e-9);
  const ImageVolume im = render_tee_frame(p.sequence, ed, g, o);
  EXPECT_EQ(im.size[0], 44);
  EXPECT_LT((im.position(21.5, 21.5, 21.5) - c).norm(), 1e-9)
      << "the cube is centred on the annulus";
  for (float v : im.data) ASSERT_TRUE(v >= 0.0f && v <= 255.0f);
  const auto [leaflet, around] = leaflet_and_surroundings(im, p.sequence.frames[ed]);
  EXPECT_GT(leaflet, around + 60.0) << "leaflet " << leaflet << " vs surroundings " << around;
}

TEST(TeeRenderer, SameSeedSameVolumeAnotherSeedAnother) {
  const Patient p = make_virtual_patient(3);
  TeeRenderOptions o = small();
  const TeeGeometry g = tee_geometry(p.sequence, o);
  const int ed = p.sequence.end_diastole;
  const ImageVolume a = render_tee_frame(p.sequence, ed, g, o);
  EXPECT_EQ(a.data, render_tee_frame(p.sequence, ed, g, o).data);
  o.seed = 6;
  EXPECT_NE(a.data, render_tee_frame(p.sequence, ed, g, o).data);
}

TEST(TeeRenderer, FullyDevelopedSpeckleHasRayleighStatistics) {
  // The log of a Rayleigh envelope has an SD of 10 log10(e) pi / sqrt(6) = 5.57 dB whatever
  // the PSF: in a uniform region the grey levels must spread by 5.57 dB of the dynamic range.
  // Blood raised above the clipping floor, no noise or drop-outs, a wide dynamic range.
  const Patient p = make_virtual_patient(3);
  const int ed = p.sequence.end_diastole;
  TeeRenderOptions o = small();
  o.blood = 0.003;
  o.dynamic_range_db = 80;
  o.noise = 0;
  o.dropout_fraction = 0;
  const TeeGeometry g = tee_geometry(p.sequence, o);
  TeeRenderOptions clean = o;
  clean.speckle = 0;
  const ImageVolume a = render_tee_frame(p.sequence, ed, g, o);
  const ImageVolume b = render_tee_frame(p.sequence, ed, g, clean);
  // Uniform blood: voxels whose clean 3x3x3 neighbourhood stays within the blood level
  // (-25 dB -> 175 grey) give or take the depth attenuation.
  double s = 0, s2 = 0, clean_s = 0, clean_s2 = 0;
  int n = 0;
  for (int k = 1; k + 1 < b.size[2]; ++k)
    for (int j = 1; j + 1 < b.size[1]; ++j)
      for (int i = 1; i + 1 < b.size[0]; ++i) {
        bool uniform = true;
        for (int dk = -1; dk <= 1 && uniform; ++dk)
          for (int dj = -1; dj <= 1 && uniform; ++dj)
            for (int di = -1; di <= 1 && uniform; ++di) {
              const double v = b.at(i + di, j + dj, k + dk);
              uniform = v > 165 && v < 186;
            }
        if (!uniform) continue;
        const double v = a.at(i, j, k), c = b.at(i, j, k);
        s += v;
        s2 += v * v;
        clean_s += c;
        clean_s2 += c * c;
        ++n;
      }
  ASSERT_GT(n, 1000) << "not enough uniform blood to measure";
  const double sd = std::sqrt(s2 / n - (s / n) * (s / n));
  const double clean_sd = std::sqrt(std::max(0.0, clean_s2 / n - (clean_s / n) * (clean_s / n)));
  const double expected = 10.0 * std::log10(std::exp(1.0)) * M_PI / std::sqrt(6.0) * 255.0 / 80.0;
  EXPECT_GT(sd, 0.75 * expected) << "speckle SD " << sd << " grey levels, Rayleigh " << expected;
  EXPECT_LT(sd, 1.15 * expected) << "speckle SD " << sd << " grey levels, Rayleigh " << expected;
  EXPECT_LT(clean_sd, 0.35 * expected) << "without speckle the region is nearly uniform";
}

TEST(TeeRenderer, ProbeJitterVariesTheViewWithinItsBounds) {
  const Patient p = make_virtual_patient(3);
  const int ed = p.sequence.end_diastole;
  const Eigen::Vector3d c = p.sequence.frames[ed].annulus.colwise().mean().transpose();
  TeeRenderOptions o = small();
  const TeeGeometry standard = tee_geometry(p.sequence, o);
  o.probe_jitter_deg = 15;
  double max_tilt = 0;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    o.seed = seed;
    const TeeGeometry g = tee_geometry(p.sequence, o);
    EXPECT_NEAR(g.axes.determinant(), 1.0, 1e-9);
    EXPECT_LT((g.axes.transpose() * g.axes - Eigen::Matrix3d::Identity()).norm(), 1e-9);
    const double depth = (g.apex - c).norm();
    EXPECT_GE(depth, o.probe_depth_mm - 8 - 1e-9);
    EXPECT_LE(depth, o.probe_depth_mm + 8 + 1e-9);
    const double tilt = std::acos(
        std::clamp((c - g.apex).normalized().dot((c - standard.apex).normalized()), -1.0, 1.0));
    EXPECT_LE(tilt, 15 * M_PI / 180 + 1e-9);
    max_tilt = std::max(max_tilt, tilt);
    const double half = 0.5 * (g.grid.size[0] - 1);
    EXPECT_LE((g.grid.position(half, half, half) - c).cwiseAbs().maxCoeff(), 6 + 1e-9);
    EXPECT_EQ(g.apex, tee_geometry(p.sequence, o).apex) << "same seed, same view";
  }
  EXPECT_GT(max_tilt, 5 * M_PI / 180) << "the views do vary";
}

TEST(TeeRenderer, InvalidOptionsAndFramesAreNamed) {
  const Patient p = make_virtual_patient(3);
  TeeRenderOptions o = small();
  o.voxel_mm = 0;
  try {
    tee_geometry(p.sequence, o);
    FAIL() << "a zero voxel size was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("voxel_mm"), std::string::npos) << e.what();
  }
  o = small();
  o.speckle = std::nan("");
  EXPECT_THROW(tee_geometry(p.sequence, o), Error);
  o = small();
  EXPECT_THROW(render_tee_frame(p.sequence, 999, tee_geometry(p.sequence, o), o), Error);
  EXPECT_THROW(tee_geometry(ValveSequence{}, o), Error);
}

}  // namespace
}  // namespace mvtwin::detection
