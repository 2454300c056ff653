#include "mvtwin/detection/segmentation_fit.h"

#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "mvtwin/core/annulus_plane.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/nifti.h"
#include "mvtwin/core/surface_mesh_io.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/detection/label_map.h"
#include "mvtwin/detection/patient_import.h"
#include "mvtwin/forward/virtual_closure.h"

#include "../support/small_models.h"

namespace mvtwin::detection {
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

using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// Mean distance from the fitted annulus points to the true annulus curve, mm.
double annulus_error(const Points& fitted, const Points& truth) {
  const Points dense = resample_closed_curve(truth, 2000);
  double s = 0;
  for (Eigen::Index u = 0; u < fitted.rows(); ++u)
    s += std::sqrt((dense.rowwise() - fitted.row(u)).rowwise().squaredNorm().minCoeff());
  return s / fitted.rows();
}

/// A virtual patient whose closing frames were simulated by a small model without noise.
const Patient& closed_patient(std::uint64_t seed) {
  static std::map<std::uint64_t, Patient> cache;
  auto it = cache.find(seed);
  if (it == cache.end()) {
    Patient q = make_virtual_patient(seed);
    forward::VirtualClosureOptions vo;
    vo.simulation = forward::ClosureOptions{};
    vo.simulation.model.ures = test_support::small_models() ? 16 : 24;
    vo.simulation.model.vres = test_support::small_models() ? 10 : 16;
    vo.simulation.dt = 0.01;
    vo.noise_mm = 0.0;
    forward::simulate_observed_closure(&q, vo);
    it = cache.emplace(seed, std::move(q)).first;
  }
  return it->second;
}

struct RoundTrip {
  double surface_mm, annulus_mm, rim_vs_label_mm;
};

RoundTrip round_trip(const ValveFrame& truth, const std::string& convention, double voxel,
                     std::uint64_t seed) {
  LabelMapOptions lo;
  lo.labels = segmentation_labels(convention);
  lo.voxel_mm = voxel;
  lo.seed = seed;
  const ImageVolume im = valve_label_map(truth, lo);
  SegmentationFitOptions fo;
  fo.labels = lo.labels;
  const FrameFit fit = fit_segmentation_frame(im, "virtual", fo);
  std::cout << "truth atrial " << atrial_direction(truth.annulus).transpose() << " fit "
            << atrial_direction(fit.frame.annulus).transpose() << "\n";
  const SymmetricDistance d = symmetric_surface_distance(fit.frame.la_surface->triangulate(),
                                                         truth.la_surface->triangulate());
  return {d.symmetric.mean, annulus_error(fit.frame.annulus, truth.annulus),
          fit.rim_vs_label ? fit.rim_vs_label->mean : std::nan("")};
}

TEST(SegmentationFit, VirtualOpenAndClosedFramesRoundTrip) {
#ifdef __SANITIZE_ADDRESS__
  // One patient at one voxel size (every code path; 102 s for all of them under ASan).
  const std::vector<std::uint64_t> seeds{1};
  const std::vector<double> voxels{0.8};
#else
  const std::vector<std::uint64_t> seeds{1, 2};
  const std::vector<double> voxels{0.5, 0.8};
#endif
  for (std::uint64_t seed : seeds) {
    const Patient& p = closed_patient(seed);
    for (const char* conv : {"mvtool", "mvseg"}) {
      for (double voxel : voxels) {
        for (int f : {p.sequence.end_diastole, p.sequence.first_closed}) {
          const RoundTrip r = round_trip(p.sequence.frames[f], conv, voxel, seed);
          std::cout << "seed " << seed << " " << conv << " voxel " << voxel << " frame "
                    << (f == p.sequence.end_diastole ? "ED    " : "closed") << ": surface "
                    << r.surface_mm << " mm, annulus " << r.annulus_mm << " mm, rim vs label "
                    << r.rim_vs_label_mm << "\n";
          EXPECT_LT(r.surface_mm, 0.5);
          EXPECT_LT(r.annulus_mm, 1.0);
        }
      }
    }
  }
}

TEST(SegmentationFit, RecoversAnAnalyticClosedValve) {
  AnalyticValve valve;
  valve.pose.rotate(Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 1, 0).normalized()));
  valve.pose.pretranslate(Eigen::Vector3d(3, -2, 1));
  const ImageVolume im = valve.rasterize();
  const FrameFit r = fit_segmentation_frame(im, "analytic", {});
  const ValveFrame& f = r.frame;
  ASSERT_TRUE(f.la_surface);
  const LeafletGrid& g = *f.la_surface;
  EXPECT_EQ(r.annulus_source, "annulus label");

  // Atrial side inferred correctly (u runs clockwise seen from the atrium).
  EXPECT_GT(atrial_direction(f.annulus).dot(valve.pose.linear() * Eigen::Vector3d::UnitZ()), 0.95);

  // Every fitted point lies on the analytic atrial surface.
  double worst = 0, sum = 0;
  int n = 0;
  for (int v = 1; v < g.vres(); ++v) {
    for (int u = 0; u < g.ures(); ++u) {
      const Eigen::Vector3d p = valve.pose.inverse() * g.at(u, v);
      if (valve.r2(p.x(), p.y()) > 0.8) continue;  // inside the annulus ring: no leaflet label
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
  // The rim of the leaflets (inside the 1 mm ring) against the ring itself.
  ASSERT_TRUE(r.rim_vs_label);
  EXPECT_LT(r.rim_vs_label->mean, 2.0);
  EXPECT_LT(r.orifice_area_mm2, 30.0);  // closed
}

TEST(SegmentationFit, BadLabelMapsAreNamed) {
  AnalyticValve valve;
  const ImageVolume im = valve.rasterize();
  SegmentationFitOptions opt;
  opt.labels = {2, 7, 1, 0, "explicit"};
  try {
    fit_segmentation_frame(im, "seg.nii.gz", opt);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("seg.nii.gz: label 7 (posterior leaflet) has 0 voxels"), std::string::npos)
        << m;
    EXPECT_NE(m.find("labels found with voxel counts: 1: "), std::string::npos) << m;
  }
  opt.labels = {1, 1, 3, 0, "explicit"};
  EXPECT_THROW(fit_segmentation_frame(im, "seg", opt), Error);
  ImageVolume empty = im;
  std::fill(empty.data.begin(), empty.data.end(), 0.0f);
  try {
    fit_segmentation_frame(empty, "empty.nrrd", {});
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("empty.nrrd: no valve found"), std::string::npos)
        << e.what();
  }
  // Cut by the field of view: the leaflets reach the image border.
  ImageVolume cut = im;
  cut.size[2] = 30;
  cut.data.resize(cut.num_voxels());
  try {
    fit_segmentation_frame(cut, "cut.nii", {});
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cut.nii: the leaflets touch the image border"),
              std::string::npos)
        << e.what();
  }
  // A second large piece of the anterior leaflet.
  ImageVolume two = im;
  for (int k = 2; k < 12; ++k)
    for (int j = 2; j < 30; ++j)
      for (int i = 2; i < 30; ++i)
        two.data[i + two.size[0] * (j + static_cast<size_t>(two.size[1]) * k)] = 2.0f;
  try {
    fit_segmentation_frame(two, "two.nii", {});
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("several disconnected components"), std::string::npos)
        << e.what();
  }
}

TEST(SegmentationFit, SwappedLabelsAreAWarningNotASilentSwap) {
  const Patient& p = closed_patient(1);
  for (int f : {p.sequence.end_diastole, p.sequence.first_closed}) {
    LabelMapOptions lo;
    lo.labels = segmentation_labels("mvseg");
    lo.voxel_mm = 0.8;
    const ImageVolume im = valve_label_map(p.sequence.frames[f], lo);
    SegmentationFitOptions right, swapped;
    right.labels = lo.labels;
    swapped.labels = {lo.labels.posterior, lo.labels.anterior, 0, 0, "explicit"};
    EXPECT_TRUE(fit_segmentation_frame(im, "right", right).warnings.empty()) << "frame " << f;
    const FrameFit w = fit_segmentation_frame(im, "swapped", swapped);
    ASSERT_FALSE(w.warnings.empty()) << "frame " << f;
    EXPECT_NE(w.warnings[0].find("swapped"), std::string::npos);
  }
}

// The real patient (mvtool case 008): manual and automatic segmentations of one closed valve.
TEST(SegmentationFit, RealValveMvtool008) {
  const fs::path dir = fs::path(MVTWIN_SHARED_DATA_DIR) / "mvtool-008";
  if (!fs::exists(dir / "008_gt.nii.gz")) {
    GTEST_SKIP() << "../shared/data/mvtool-008 absent (a user's clone has no ../shared): skipped";
  }
  const ImageVolume gt_map = read_nifti(dir / "008_gt.nii.gz");
  const FrameFit gt = fit_segmentation_frame(gt_map, "008_gt");
  const FrameFit pred = fit_segmentation_frame(read_nifti(dir / "008_pred.nii.gz"), "008_pred");
  SegmentationFitOptions rim;
  rim.use_annulus_label = false;
  const FrameFit gt_rim = fit_segmentation_frame(gt_map, "008_gt", rim);
  auto show = [](const char* what, const DistanceStats& d) {
    std::cout << what << d.mean << " +- " << d.sd << " mm (p95 " << d.p95 << ", max " << d.max
              << ")\n";
  };
  show("008_gt   surface -> mask boundary: ", gt.surface_to_mask);
  show("008_gt   atrial mask -> surface:   ", gt.mask_to_surface);
  show("008_pred surface -> mask boundary: ", pred.surface_to_mask);
  show("008_pred atrial mask -> surface:   ", pred.mask_to_surface);
  ASSERT_TRUE(gt.rim_vs_label);
  show("008_gt   rim annulus vs label:     ", *gt.rim_vs_label);
  const SymmetricDistance d = symmetric_surface_distance(gt.frame.la_surface->triangulate(),
                                                         pred.frame.la_surface->triangulate());
  show("symmetric gt <-> pred:             ", d.symmetric);
  const SymmetricDistance dr = symmetric_surface_distance(gt.frame.la_surface->triangulate(),
                                                          gt_rim.frame.la_surface->triangulate());
  show("gt: label annulus vs rim surfaces:  ", dr.symmetric);
  EXPECT_EQ(gt_rim.annulus_source, "leaflet rim");
  EXPECT_TRUE(gt.warnings.empty()) << gt.warnings.front();  // labels as the expert gave them
  EXPECT_LT(gt.surface_to_mask.mean, 0.6);
  EXPECT_LT(pred.surface_to_mask.mean, 0.6);
  EXPECT_LT(gt.mask_to_surface.mean, 1.5);
  EXPECT_LT(d.symmetric.mean, 3.0);
  // The annulus from the leaflet rim lies on the labelled annulus (within 1.5 mm of its
  // voxels); its centreline is the ring's half-width (~2 mm here) further out, because the
  // leaflet labels stop where the ring label starts.
  ASSERT_TRUE(gt.rim_to_label_voxels);
  show("008_gt   rim annulus -> ring voxels: ", *gt.rim_to_label_voxels);
  EXPECT_LT(gt.rim_to_label_voxels->mean, 1.5);
  EXPECT_LT(gt.rim_vs_label->mean, 2.5);
  EXPECT_LT((gt.frame.annulus.row(0) - pred.frame.annulus.row(0)).norm(), 6.0);
}

// The same virtual frames given as leaflet surface meshes (as other tools export them): one file
// per leaflet, or both leaflets in one file.
TEST(SegmentationFit, LeafletSurfaceMeshes) {
  const Patient& p = closed_patient(2);
  const fs::path dir = fs::temp_directory_path() / "mvtwin_mesh_fit_test";
  fs::create_directories(dir);
  for (int f : {p.sequence.end_diastole, p.sequence.first_closed}) {
    const ValveFrame& truth = p.sequence.frames[f];
    auto [anterior_mesh, posterior_mesh] = leaflet_surface_meshes(*truth.la_surface, 48, 30);
    TriangleMesh leaf[2] = {anterior_mesh, posterior_mesh};
    write_surface_mesh(dir / "anterior.stl", leaf[0]);
    write_surface_mesh(dir / "posterior.ply", leaf[1]);
    const FrameFit two = fit_surface_frame(read_surface_mesh(dir / "anterior.stl").mesh,
                                           read_surface_mesh(dir / "posterior.ply").mesh, "meshes");
    const double e2 = symmetric_surface_distance(two.frame.la_surface->triangulate(),
                                                 truth.la_surface->triangulate())
                          .symmetric.mean;
    const double a2 = annulus_error(two.frame.annulus, truth.annulus);
    std::cout << "frame " << f << ": two mesh files: surface " << e2 << " mm, annulus " << a2
              << " mm\n";
    EXPECT_LT(e2, 0.5);
    EXPECT_LT(a2, 1.0);
    EXPECT_LT(two.surface_to_mask.mean, 1e-6);  // on the meshes
    // Both leaflets in one file: split into its two pieces (the commissure columns are shared by
    // the grid's leaflets, so here the pieces come from separate vertex copies).
    TriangleMesh both;
    both.V.resize(leaf[0].V.rows() + leaf[1].V.rows(), 3);
    both.V << leaf[0].V, leaf[1].V;
    both.F.resize(leaf[0].F.rows() + leaf[1].F.rows(), 3);
    both.F << leaf[0].F, (leaf[1].F.array() + static_cast<int>(leaf[0].V.rows())).matrix();
    write_surface_mesh(dir / "both.vtp", both, "RAS");
    const auto [a, b] = split_leaflet_meshes(read_surface_mesh(dir / "both.vtp").mesh, "both.vtp");
    EXPECT_EQ(a.F.rows(), leaf[0].F.rows()) << "the anterior leaflet is told apart by its shape";
    const FrameFit one = fit_surface_frame(a, b, "both.vtp");
    const double e1 = symmetric_surface_distance(one.frame.la_surface->triangulate(),
                                                 truth.la_surface->triangulate())
                          .symmetric.mean;
    EXPECT_LT(e1, 0.5);
  }
  // One connected surface cannot be split into leaflets.
  EXPECT_THROW(split_leaflet_meshes(
                   p.sequence.frames[p.sequence.end_diastole].la_surface->triangulate(), "one.stl"),
               Error);
}

// A 3D Slicer segmentation whose segments overlap is stored as layers; each segment is found by
// its name on its layer, with its own label value.
TEST(SlicerSegmentation, SegmentsByNameAcrossLayers) {
  ImageVolume a;
  a.size = {4, 1, 1};
  a.data = {1, 2, 0, 1};  // layer 0: "Anterior leaflet" = 1, "aorta" = 2
  ImageVolume b = a;
  b.data = {0, 0, 5, 5};  // layer 1: "PML" = 5, overlapping the anterior leaflet at voxel 3
  const std::map<std::string, std::string> fields = {{"Segment0_Name", "Anterior leaflet"},
                                                     {"Segment0_LabelValue", "1"},
                                                     {"Segment0_Layer", "0"},
                                                     {"Segment1_Name", "aorta"},
                                                     {"Segment1_LabelValue", "2"},
                                                     {"Segment1_Layer", "0"},
                                                     {"Segment2_Name", "PML"},
                                                     {"Segment2_LabelValue", "5"},
                                                     {"Segment2_Layer", "1"}};
  ASSERT_TRUE(is_slicer_segmentation(fields));
  const NamedSegmentation s = slicer_segmentation({a, b}, fields, "valve.seg.nrrd");
  EXPECT_EQ(s.labels.anterior, 2);
  EXPECT_EQ(s.labels.posterior, 3);
  EXPECT_EQ(s.labels.annulus, 0);
  EXPECT_EQ(s.label_map.data, (std::vector<float>{2, 0, 3, 3}));  // the aorta is not the valve
  auto expect = [&](std::map<std::string, std::string> f, const std::string& part) {
    try {
      slicer_segmentation({a, b}, f, "bad.seg.nrrd");
      FAIL() << "expected an error with " << part;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("bad.seg.nrrd: " + part), std::string::npos) << e.what();
    }
  };
  auto f = fields;
  f["Segment2_Name"] = "mitral annulus";
  expect(f, "the segment names");
  f = fields;
  f["Segment1_Name"] = "AML";
  expect(f, "two segments are the anterior");
  f = fields;
  f["Segment2_Layer"] = "7";
  expect(f, "segment 'PML' is on layer 7 of 2");
  f = fields;
  f["Segment2_LabelValue"] = "five";
  expect(f, "Segment2_LabelValue is not a valid number");
  EXPECT_FALSE(is_slicer_segmentation({{"space", "RAS"}}));
}

TEST(PatientImport, FramesPhasesPapillaryLabelAndAssumptions) {
  const Patient& p = closed_patient(1);
  const ValveSequence& s = p.sequence;
  LabelMapOptions lo;
  lo.labels = segmentation_labels("mvtool");
  lo.labels.papillary = 4;
  lo.voxel_mm = 0.8;
  std::vector<LabelFrame> frames;
  for (int f : {s.first_closed, s.end_diastole}) {  // out of order on purpose
    lo.seed = static_cast<std::uint64_t>(f);
    frames.push_back({valve_label_map(s.frames[f], lo), s.frames[f].time_s,
                      "frame" + std::to_string(f), std::nullopt, std::nullopt});
  }
  PatientImportOptions o;
  o.fit.labels = lo.labels;
  const PatientImport r = import_patient(frames, {}, o);
  const ValveSequence& q = r.patient.sequence;
  ASSERT_EQ(q.num_frames(), 2);
  EXPECT_EQ(q.end_diastole, 0);  // the open frame, found from the orifice
  EXPECT_EQ(q.first_closed, 1);
  EXPECT_GT(r.fits[0].orifice_area_mm2, 5 * r.fits[1].orifice_area_mm2);
  EXPECT_FALSE(r.patient.synthetic);
  EXPECT_TRUE(r.assumed.empty());
  for (int k = 0; k < 2; ++k) {
    const ValveFrame& truth = s.frames[k ? s.first_closed : s.end_diastole];
    for (Landmark l :
         {Landmark::kAnterolateralPapillaryTip, Landmark::kPosteromedialPapillaryTip}) {
      EXPECT_FALSE(q.frames[k].assumed(l));
      EXPECT_LT((q.frames[k].landmark(l) - truth.landmark(l)).norm(), 1.0)
          << name(l) << " frame " << k;
    }
  }
  // Without the papillary label the tips are assumed, said so, and near the truth's anatomy.
  for (auto& f : frames) f.labels_override = segmentation_labels("mvtool");
  const PatientImport a = import_patient(frames, {}, o);
  EXPECT_TRUE(a.patient.sequence.frames[0].assumed(Landmark::kAnterolateralPapillaryTip));
  EXPECT_EQ(a.patient.sequence.assumed_landmarks(),
            "anterolateral_papillary_tip, posteromedial_papillary_tip");
  EXPECT_EQ(a.assumed.size(), 2u);
  EXPECT_NE(a.patient.provenance.source.find("ASSUMED"), std::string::npos);
  const double err = (a.patient.sequence.frames[0].landmark(Landmark::kAnterolateralPapillaryTip) -
                      s.frames[s.end_diastole].landmark(Landmark::kAnterolateralPapillaryTip))
                         .norm();
  std::cout << "assumed anterolateral tip vs the virtual patient's: " << err << " mm\n";
  EXPECT_LT(err, 12.0);
  // Landmarks given in one frame win there and are held (assumed) in the other.
  const Eigen::Vector3d tip =
      s.frames[s.end_diastole].landmark(Landmark::kAnterolateralPapillaryTip);
  const PatientImport g = import_patient(frames,
                                         {{Landmark::kAnterolateralPapillaryTip, tip,
                                           s.frames[s.end_diastole].time_s, "tips.mrk.json"}},
                                         o);
  EXPECT_EQ(g.patient.sequence.frames[0].landmark(Landmark::kAnterolateralPapillaryTip), tip);
  EXPECT_FALSE(g.patient.sequence.frames[0].assumed(Landmark::kAnterolateralPapillaryTip));
  EXPECT_TRUE(g.patient.sequence.frames[1].assumed(Landmark::kAnterolateralPapillaryTip));
  // Markups in another space (here: IJK indices) are refused.
  EXPECT_THROW(import_patient(frames,
                              {{Landmark::kAnterolateralPapillaryTip, Eigen::Vector3d(150, 160, 40),
                                std::nullopt, "ijk.mrk.json"}},
                              o),
               Error);
  // Duplicate times, and frames of another patient (grids that disagree), are refused.
  std::vector<LabelFrame> dup = frames;
  dup[1].time_s = dup[0].time_s;
  EXPECT_THROW(import_patient(dup, {}, o), Error);
  std::vector<LabelFrame> mixed = frames;
  mixed[0].labels = valve_label_map(
      closed_patient(2).sequence.frames[closed_patient(2).sequence.first_closed], lo);
  try {
    import_patient(mixed, {}, o);
    FAIL() << "expected frames of two patients to be refused";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("disagree"), std::string::npos) << e.what();
  }
}

TEST(PatientImport, MarkupLabels) {
  EXPECT_EQ(landmark_from_label("Anterolateral papillary tip"),
            Landmark::kAnterolateralPapillaryTip);
  EXPECT_EQ(landmark_from_label("ALPM"), Landmark::kAnterolateralPapillaryTip);
  EXPECT_EQ(landmark_from_label("PM papillary"), Landmark::kPosteromedialPapillaryTip);
  EXPECT_EQ(landmark_from_label("posteromedial_papillary_tip"),
            Landmark::kPosteromedialPapillaryTip);
  EXPECT_EQ(landmark_from_label("left trigone"), Landmark::kAnterolateralTrigone);
  EXPECT_EQ(landmark_from_label("PM commissure"), Landmark::kPosteromedialCommissure);
  EXPECT_EQ(landmark_from_label("Posterior annulus midpoint"), Landmark::kPosteriorAnnulusMidpoint);
  EXPECT_FALSE(landmark_from_label("F-1"));
  MarkupList m;
  m.points = {{"F-1", {1, 2, 3}}, {"F-2", {4, 5, 6}}};
  const auto two =
      landmarks_from_markups(m, "tips.fcsv", std::nullopt);  // two unlabelled: the tips, in order
  ASSERT_EQ(two.size(), 2u);
  EXPECT_EQ(two[1].landmark, Landmark::kPosteromedialPapillaryTip);
  m.points.push_back({"F-3", {7, 8, 9}});
  EXPECT_THROW(landmarks_from_markups(m, "three.fcsv", std::nullopt), Error);
  const auto ordered =
      landmarks_from_markups(m, "three.fcsv", 0.1,
                             {Landmark::kAnterolateralTrigone, Landmark::kPosteromedialTrigone,
                              Landmark::kAnterolateralPapillaryTip});
  EXPECT_EQ(ordered[2].landmark, Landmark::kAnterolateralPapillaryTip);
  EXPECT_EQ(*ordered[2].time_s, 0.1);
  EXPECT_EQ(segment_role("Anterior Leaflet"), "anterior");
  EXPECT_EQ(segment_role("mitral_annulus"), "annulus");
  EXPECT_EQ(segment_role("PML"), "posterior");
  EXPECT_EQ(segment_role("Papillary muscles"), "papillary");
  EXPECT_EQ(segment_role("aorta"), "");
}

}  // namespace
}  // namespace mvtwin::detection
