#include "mvtwin/detection/valve_detector.h"

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "mvtwin/core/error.h"
#include "mvtwin/core/point_to_mesh_distance.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/detection/tee_renderer.h"

namespace mvtwin::detection {
namespace {

struct Case {
  Patient patient;
  std::vector<int> frames;
  std::vector<ImageVolume> images;
};

/// Virtual patients' open frames rendered as small TEE volumes, each with its own probe pose.
std::vector<Case> cohort(std::uint64_t first, int n) {
  std::vector<Case> out;
  for (int i = 0; i < n; ++i) {
    Case c{make_virtual_patient(first + static_cast<std::uint64_t>(i)), {}, {}};
    TeeRenderOptions o;
    o.voxel_mm = 1.5;
    o.box_mm = 72;
    o.probe_jitter_deg = 10;
    o.seed = first + static_cast<std::uint64_t>(i);
    const TeeGeometry g = tee_geometry(c.patient.sequence, o);
    const int ed = c.patient.sequence.end_diastole;
    for (int f : {ed, ed / 2}) {
      c.frames.push_back(f);
      c.images.push_back(render_tee_frame(c.patient.sequence, f, g, o));
    }
    out.push_back(std::move(c));
  }
  return out;
}

double surface_error(const ValveFrame& detected, const ValveFrame& truth) {
  return symmetric_surface_distance(detected.la_surface->triangulate(),
                                    truth.la_surface->triangulate())
      .symmetric.mean;
}

TEST(ValveDetector, BeatsTheMeanShapeBaselineOnHeldOutVolumesAndSurvivesASaveLoad) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "training forests takes too long under AddressSanitizer";
#endif
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<Case> train = cohort(1, 7), test = cohort(701, 2);
  const auto t1 = std::chrono::steady_clock::now();
  std::vector<TrainingVolume> data;
  for (const Case& c : train)
    for (std::size_t k = 0; k < c.frames.size(); ++k)
      data.push_back(
          {&c.images[k], &c.patient.sequence.frames[static_cast<std::size_t>(c.frames[k])]});
  DetectorOptions o;
  o.trees = 25;
  o.samples_per_volume = 800;
  const ValveDetector d = ValveDetector::train(data, o);
  const auto t2 = std::chrono::steady_clock::now();
  RecordProperty("render_s", std::to_string(std::chrono::duration<double>(t1 - t0).count()));
  RecordProperty("train_s", std::to_string(std::chrono::duration<double>(t2 - t1).count()));
  double detect_s = 0;
  double detected = 0, baseline = 0, centre = 0;
  int n = 0;
  for (const Case& c : test) {
    for (std::size_t k = 0; k < c.frames.size(); ++k) {
      const ValveFrame& truth = c.patient.sequence.frames[static_cast<std::size_t>(c.frames[k])];
      DetectionInfo info;
      const ValveFrame f = d.detect(c.images[k], nullptr, &info);
      detect_s += info.seconds;
      ASSERT_TRUE(f.la_surface);
      detected += surface_error(f, truth);
      centre += (info.centre - truth.annulus.colwise().mean().transpose()).norm();
      // Baseline without the image's content: the mean shape placed by the mean landmark
      // offsets around the volume's centre.
      ValveFrame b;
      const ImageVolume& im = c.images[k];
      const double h = 0.5 * (im.size[0] - 1);
      const Eigen::Vector3d mid = im.position(h, h, h);
      Points3 L(static_cast<Eigen::Index>(kPlacingLandmarks.size()), 3);
      const Points3 mean_l = d.shape().mean_landmarks();
      // The mean landmark configuration, scaled to the training valves' size, at mid.
      const Similarity s = fit_similarity(
          d.shape().mean_landmarks(),
          placing_landmarks(
              train[0].patient.sequence.frames[static_cast<std::size_t>(train[0].frames[0])]));
      for (Eigen::Index r = 0; r < L.rows(); ++r)
        L.row(r) = (mid + s.scale * im.direction * mean_l.row(r).transpose()).transpose();
      b.la_surface = LeafletGrid(d.shape().ures(), d.shape().vres(), d.shape().place_mean(L));
      baseline += surface_error(b, truth);
      ++n;
    }
  }
  detected /= n;
  baseline /= n;
  centre /= n;
  RecordProperty("detect_s_per_volume", std::to_string(detect_s / n));
  RecordProperty("detected_mm", std::to_string(detected));
  RecordProperty("baseline_mm", std::to_string(baseline));
  RecordProperty("centre_error_mm", std::to_string(centre));
  EXPECT_LT(detected, 0.7 * baseline)
      << "detected " << detected << " mm, mean-shape baseline " << baseline << " mm";
  EXPECT_LT(centre, 6.0);

  // Save and load: the same detections.
  const auto dir =
      std::filesystem::temp_directory_path() / ("mvtwin_det_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  d.save(dir / "m.yml.gz", {{"test", "yes"}});
  const ValveDetector back = ValveDetector::load(dir / "m.yml.gz");
  const ValveFrame a = d.detect(test[0].images[0]), b = back.detect(test[0].images[0]);
  EXPECT_LT((a.la_surface->points() - b.la_surface->points()).cwiseAbs().maxCoeff(), 1e-6);
  { std::ofstream(dir / "bad.yml") << "%YAML:1.0\n---\nformat: something-else\n"; }
  EXPECT_THROW(ValveDetector::load(dir / "bad.yml"), Error);
  EXPECT_THROW(ValveDetector::load(dir / "missing.yml.gz"), Error);
  EXPECT_THROW(d.save(dir / "m.txt", {}), Error);
  std::filesystem::remove_all(dir);
}

TEST(ValveDetector, ClosedFramesGetTheirTipsFromTheSurfaceAsOpenFramesDefineThem) {
  const Patient p = make_virtual_patient(5);
  const ValveFrame& ed = p.sequence.frames[static_cast<std::size_t>(p.sequence.end_diastole)];
  const auto a = static_cast<std::size_t>(index(Landmark::kAnteriorLeafletTip));
  const auto b = static_cast<std::size_t>(index(Landmark::kPosteriorLeafletTip));
  ASSERT_TRUE(ed.landmark_observed[a] && ed.landmark_observed[b]);
  // An open frame's observed tips are the surface's free-edge middles: the rule reproduces them.
  ValveFrame hidden = ed;
  hidden.landmark_observed[a] = hidden.landmark_observed[b] = false;
  hidden.landmarks[a].setConstant(std::nan(""));
  const ValveFrame filled = with_surface_tips(hidden);
  EXPECT_TRUE(filled.landmark_observed[a] && filled.landmark_observed[b]);
  EXPECT_LT((filled.landmarks[a] - ed.landmarks[a]).norm(), 1e-6);
  EXPECT_LT((filled.landmarks[b] - ed.landmarks[b]).norm(), 1e-6);
  // Observed tips are kept as they are; a frame without a surface is left alone.
  ValveFrame moved = ed;
  moved.landmarks[a] += Eigen::Vector3d(1, 2, 3);
  EXPECT_EQ(with_surface_tips(moved).landmarks[a], moved.landmarks[a]);
  ValveFrame bare = hidden;
  bare.la_surface.reset();
  EXPECT_FALSE(with_surface_tips(bare).landmark_observed[a]);
}

TEST(ValveDetector, RefusesTooLittleTrainingDataAndBadOptions) {
  EXPECT_THROW(ValveDetector::train({}, DetectorOptions{}), Error);
  DetectorOptions o;
  o.scales.clear();
  EXPECT_THROW(ValveDetector::train({}, o), Error);
  EXPECT_THROW(ValveDetector{}.detect(ImageVolume{}), Error);
}

// Found by the fuzzer (tests/fuzz/fuzz_detector_model.cpp): a model file whose seed is out of
// range was cast to an integer (undefined behaviour), and OpenCV's exceptions for malformed
// nodes escaped load() as cv::Exception. Both are mvtwin::Error naming the file now.
TEST(ValveDetector, MalformedModelFilesGetAnErrorNamingTheFile) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("mvtwin_det_bad_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::string head = "%YAML:1.0\n---\nformat: mvtwin-valve-detector\nformat_version: 1\n";
  const std::string options =
      "options:\n   trees: 2\n   max_depth: 4\n   samples_per_volume: 100\n"
      "   position_step_mm: 2.\n   landmark_search_mm: 6.\n   track_search_mm: 4.\n"
      "   normal_search_mm: 3.\n   surface_iterations: 2\n";
  auto error_of = [&](const std::string& name, const std::string& text) {
    { std::ofstream(dir / name) << text; }
    try {
      ValveDetector::load(dir / name);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  std::string e = error_of("seed.yml", head + "scales: [ 4, 2 ]\n" + options + "   seed: 1e308\n");
  EXPECT_NE(e.find("seed.yml"), std::string::npos) << e;
  EXPECT_NE(e.find("the seed is not a whole number"), std::string::npos) << e;
  e = error_of("scales.yml", head + "scales: [ a, b ]\n" + options + "   seed: 1\n");
  EXPECT_NE(e.find("scales.yml"), std::string::npos) << e;
  EXPECT_NE(e.find("not a readable detector model"), std::string::npos) << e;
  // Text OpenCV 4.6's YAML parser never returns from (found by the fuzzer: several documents
  // with NUL bytes between them) is refused before it reaches the parser.
  e = error_of("hang.yml", std::string("%YAML:1.ts:0\n----p-\0%YAML:1.0\ns:0\n----p-", 40));
  EXPECT_NE(e.find("hang.yml"), std::string::npos) << e;
  EXPECT_NE(e.find("NUL byte"), std::string::npos) << e;
  e = error_of("two.yml", head + "scales: [ 4, 2 ]\n---\nformat: mvtwin-valve-detector\n");
  EXPECT_NE(e.find("more than one YAML document"), std::string::npos) << e;
  e = error_of("bracket.yml", head + "scales: [ 4., [ 2.\n");
  EXPECT_NE(e.find("unclosed quote or bracket"), std::string::npos) << e;
  e = error_of("latin1.yml", head + "scales: [ 4., 2\xbf ]\n");
  EXPECT_NE(e.find("byte 191"), std::string::npos) << e;
  e = error_of("flow.yml", "%YAML:1.0\n---\n[1.]\n[ --- ]\n[ ,]\n");
  EXPECT_NE(e.find("more than one YAML document"), std::string::npos) << e;
  e = error_of("list.yml", "%YAML:1.0\n---\n[1.]\n");
  EXPECT_NE(e.find("neither a key nor indented"), std::string::npos) << e;
  e = error_of("empty.yml", head + "scales: [ 4., , 2. ]\n");
  EXPECT_NE(e.find("an empty item"), std::string::npos) << e;
  e = error_of("json.yml", "{\"format\": \"mvtwin-valve-detector\"}");
  EXPECT_NE(e.find("must start with '%YAML:1.0'"), std::string::npos) << e;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace mvtwin::detection
