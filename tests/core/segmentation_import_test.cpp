#include "mvtwin/core/segmentation_import.h"

#include <cmath>
#include <filesystem>
#include <iostream>
#include <numbers>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "mvtwin/core/annulus_plane.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/nifti.h"

namespace mvtwin {
namespace {

using std::numbers::pi;
namespace fs = std::filesystem;

// An analytic closed valve in its own frame (x anterior, y anterolateral, z atrium): saddle
// elliptic annulus, leaflets tenting 6 mm into the ventricle, the coaptation line
// x = xc(y) separating the anterior (x > xc) from the posterior leaflet, 1.3 mm thick.
struct AnalyticValve {
  double a = 14, b = 18, saddle = 5, tent = 6, thickness = 1.3;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();

  double xc(double y) const { return -3.0 + 0.015 * y * y; }
  double r2(double x, double y) const { return (x / a) * (x / a) + (y / b) * (y / b); }
  double top(double x, double y) const {  // atrial surface height
    const double th = std::atan2(y / b, x / a);
    const double q = r2(x, y);
    return q * 0.5 * saddle * std::cos(2 * th) - tent * (1 - q);
  }
  Eigen::Vector3d annulus(double th) const {
    return {a * std::cos(th), b * std::sin(th), 0.5 * saddle * std::cos(2 * th)};
  }

  ImageVolume rasterize() const {
    ImageVolume im;
    im.spacing = Eigen::Vector3d::Constant(0.5);
    im.size = {100, 100, 70};
    im.origin = pose * Eigen::Vector3d(-25, -25, -17);
    im.direction = Eigen::Matrix3d::Identity();
    im.data.assign(im.num_voxels(), 0.0f);
    // Sample the annulus densely for the ring label.
    std::vector<Eigen::Vector3d> ring;
    for (int i = 0; i < 720; ++i) ring.push_back(annulus(2 * pi * i / 720));
    for (int k = 0; k < im.size[2]; ++k) {
      for (int j = 0; j < im.size[1]; ++j) {
        for (int i = 0; i < im.size[0]; ++i) {
          const Eigen::Vector3d p = pose.inverse() * im.position(i, j, k);
          float label = 0;
          if (r2(p.x(), p.y()) < 1.0) {
            const double h = top(p.x(), p.y());
            if (p.z() <= h && p.z() >= h - thickness) label = p.x() > xc(p.y()) ? 2.0f : 3.0f;
          }
          const double rr = r2(p.x(), p.y());
          if (rr > 0.75 && rr < 1.3) {  // near the ring: test the nearby ring samples only
            const double th = std::atan2(p.y() / b, p.x() / a);
            const int c = static_cast<int>(std::lround(th / (2 * pi) * 720)) + 720;
            for (int o = -24; o <= 24; ++o) {
              if ((ring[(c + o) % 720] - p).squaredNorm() < 1.0) {
                label = 1.0f;
                break;
              }
            }
          }
          im.data[i + im.size[0] * (j + static_cast<size_t>(im.size[1]) * k)] = label;
        }
      }
    }
    return im;
  }
};

TEST(SegmentationImport, RecoversAnAnalyticClosedValve) {
  AnalyticValve valve;
  valve.pose.rotate(Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 1, 0).normalized()));
  valve.pose.pretranslate(Eigen::Vector3d(3, -2, 1));
  const ImageVolume im = valve.rasterize();
  SegmentationImportOptions opt;
  opt.keep_label_map = false;
  const SegmentationImport r = import_segmentation(im, "analytic", opt);
  const ValveFrame& f = r.patient.sequence.frames.at(0);
  ASSERT_TRUE(f.la_surface);
  const LeafletGrid& g = *f.la_surface;

  // Atrial side inferred correctly (u runs clockwise seen from the atrium).
  EXPECT_GT(atrial_direction(f.annulus).dot(valve.pose.linear() * Eigen::Vector3d::UnitZ()), 0.95);

  // Every fitted point lies on the analytic atrial surface (or the annulus ring).
  double worst = 0, sum = 0;
  int n = 0;
  for (int v = 1; v < g.vres(); ++v) {
    for (int u = 0; u < g.ures(); ++u) {
      const Eigen::Vector3d p = valve.pose.inverse() * g.at(u, v);
      const double e = std::abs(p.z() - valve.top(p.x(), p.y()));
      worst = std::max(worst, e);
      sum += e;
      ++n;
    }
  }
  std::cout << "analytic valve: fitted LA surface vs truth, mean " << sum / n << " mm, max "
            << worst << " mm\n";
  EXPECT_LT(sum / n, 0.3);
  EXPECT_LT(worst, 1.5);

  // The annulus runs through the ring centre.
  for (int u = 0; u < g.ures(); ++u) {
    const Eigen::Vector3d p = valve.pose.inverse() * f.annulus.row(u).transpose();
    const double th = std::atan2(p.y() / valve.b, p.x() / valve.a);
    EXPECT_LT((p - valve.annulus(th)).norm(), 0.8) << "u=" << u;
  }
  // Commissures where the coaptation line meets the annulus; u = 0 on the anterolateral (+y) side.
  const Eigen::Vector3d cal = valve.pose.inverse() * f.annulus.row(0).transpose();
  const Eigen::Vector3d cpm = valve.pose.inverse() * f.annulus.row(g.ures() / 2).transpose();
  EXPECT_GT(cal.y(), 10.0);
  EXPECT_LT(cpm.y(), -10.0);
  EXPECT_LT(std::abs(cal.x() - valve.xc(cal.y())), 3.0);
  EXPECT_LT(std::abs(cpm.x() - valve.xc(cpm.y())), 3.0);
  // The anterior leaflet is anterior; free edges lie on the coaptation line.
  EXPECT_GT((valve.pose.inverse() * g.at(g.ures() / 4, g.vres() / 2)).x(), 0.0);
  EXPECT_LT((valve.pose.inverse() * g.at(3 * g.ures() / 4, g.vres() / 2)).x(), 0.0);
  for (int u = 3; u < g.ures() / 2 - 2; ++u) {
    const Eigen::Vector3d e = valve.pose.inverse() * g.at(u, g.vres() - 1);
    EXPECT_LT(std::abs(e.x() - valve.xc(e.y())), 1.0) << "u=" << u;
  }
  EXPECT_LT(r.surface_to_mask.mean, 0.3);
}

TEST(SegmentationImport, WrongLabelsAreNamed) {
  AnalyticValve valve;
  const ImageVolume im = valve.rasterize();
  SegmentationImportOptions opt;
  opt.labels = {1, 2, 7};
  try {
    import_segmentation(im, "seg.nii.gz", opt);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("seg.nii.gz: label 7 (posterior leaflet) has 0 voxels"), std::string::npos)
        << m;
    EXPECT_NE(m.find("labels found with voxel counts: 1: "), std::string::npos) << m;
  }
  opt.labels = {1, 1, 3};
  EXPECT_THROW(import_segmentation(im, "seg", opt), Error);
  ImageVolume empty = im;
  std::fill(empty.data.begin(), empty.data.end(), 0.0f);
  EXPECT_THROW(import_segmentation(empty, "seg", {}), Error);
}

// The real patient (mvtool case 008): manual and automatic segmentations of one closed valve.
TEST(SegmentationImport, RealValveMvtool008) {
  const fs::path dir = fs::path(MVTWIN_SHARED_DATA_DIR) / "mvtool-008";
  if (!fs::exists(dir / "008_gt.nii.gz")) {
    GTEST_SKIP() << "../shared/data/mvtool-008 absent (a user's clone has no ../shared): skipped";
  }
  const SegmentationImport gt = import_segmentation(read_nifti(dir / "008_gt.nii.gz"), "008_gt");
  const SegmentationImport pred =
      import_segmentation(read_nifti(dir / "008_pred.nii.gz"), "008_pred");
  auto show = [](const char* what, const DistanceStats& d) {
    std::cout << what << d.mean << " +- " << d.sd << " mm (p95 " << d.p95 << ", max " << d.max
              << ")\n";
  };
  show("008_gt   surface -> mask boundary: ", gt.surface_to_mask);
  show("008_gt   atrial mask -> surface:   ", gt.mask_to_surface);
  show("008_pred surface -> mask boundary: ", pred.surface_to_mask);
  show("008_pred atrial mask -> surface:   ", pred.mask_to_surface);
  const SymmetricDistance d =
      symmetric_surface_distance(gt.patient.sequence.frames[0].la_surface->triangulate(),
                                 pred.patient.sequence.frames[0].la_surface->triangulate());
  show("fitted gt -> fitted pred:          ", d.a_to_b);
  show("fitted pred -> fitted gt:          ", d.b_to_a);
  show("symmetric gt <-> pred:             ", d.symmetric);
  // The fit lies on the segmentation boundary to within about a voxel (0.5 mm) ...
  EXPECT_LT(gt.surface_to_mask.mean, 0.6);
  EXPECT_LT(pred.surface_to_mask.mean, 0.6);
  // ... and covers the atrial side of the mask.
  EXPECT_LT(gt.mask_to_surface.mean, 1.5);
  // The manual-vs-automatic difference is a real detection noise level: a few mm at most.
  EXPECT_LT(d.symmetric.mean, 3.0);
  // Correspondence: both fits put u = 0 at the same commissure.
  EXPECT_LT((gt.patient.sequence.frames[0].annulus.row(0) -
             pred.patient.sequence.frames[0].annulus.row(0))
                .norm(),
            6.0);
}

}  // namespace
}  // namespace mvtwin
