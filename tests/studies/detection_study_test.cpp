// The detection study: a detector trained on one virtual cohort and measured on another, at
// several noise levels; resumable, extendable, and refusing a model that saw a test patient.
#include "mvtwin/studies/detection_study.h"

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "mvtwin/core/error.h"
#include "mvtwin/core/table_file.h"

#include "../support/small_models.h"

namespace fs = std::filesystem;
using namespace mvtwin;
using namespace mvtwin::studies;
using nlohmann::json;

namespace {

class DetectionStudy : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("mvtwin_det_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  DetectionStudyOptions quick(const std::string& name) const {
    DetectionStudyOptions o = DetectionStudyOptions::quick();
    if (test_support::small_models()) {  // coarser images, wider beams: cheaper to render
      o.render.voxel_mm = 3.0;
      o.render.axial_psf_mm = 0.8;
      o.render.lateral_psf_mm = 3.0;
    }
    o.out = dir_ / name;
    o.cache = dir_ / "cache";
    return o;
  }
  fs::path dir_;
};

TEST_F(DetectionStudy, InvalidOptionsAreRefusedNamingTheProblem) {
  auto refused = [&](DetectionStudyOptions o, const std::string& what) {
    std::string e;
    EXPECT_FALSE(o.is_valid(&e)) << what;
    EXPECT_NE(e.find(what), std::string::npos) << e;
    auto pool = make_local_pool();
    EXPECT_THROW(run_detection_study(o, *pool), Error) << what;
    EXPECT_FALSE(fs::exists(o.out)) << what;  // nothing written
  };
  DetectionStudyOptions o = quick("bad");
  o.noise_levels = {0.004, -1};
  refused(o, "noise levels");
  o = quick("bad");
  o.noise_levels = {0.004, 0.004};
  refused(o, "given twice");
  o = quick("bad");
  o.noise_levels.clear();
  refused(o, "no noise level");
  o = quick("bad");
  o.train = 2;
  refused(o, "training patients");
  o = quick("bad");
  o.model_file = dir_ / "absent.yml.gz";
  refused(o, "no model file");
  o = quick("bad");
  o.truth_sets = {"ures=abc"};
  refused(o, "truth model");
  o = quick("bad");
  o.render.voxel_mm = -1;
  refused(o, "detection study");
}

TEST_F(DetectionStudy, QuickStudyMeasuresEveryLevelResumesAndExtends) {
  DetectionStudyOptions o = quick("study");
  o.noise_levels = {0.004, 0.1};
  auto pool = make_local_pool();
  const DetectionStudyResult r = run_detection_study(o, *pool);
  ASSERT_EQ(r.runs.size(), 2u);  // 1 test patient x 2 levels
  for (const auto& run : r.runs) {
    ASSERT_TRUE(run.ok) << run.reason;
    EXPECT_NE(run.id.find("virtual-"), std::string::npos);
    EXPECT_GT(run.frames.size(), 10u);
  }
  ASSERT_EQ(r.curve.size(), 2u);
  EXPECT_EQ(r.headline["noise"], 0.004);
  const double e0 = r.headline["error_mean_mm"].get<double>();
  EXPECT_TRUE(std::isfinite(e0) && e0 > 0 && e0 < 10) << e0;
  EXPECT_EQ(r.training_patients.size(), 3u);
  EXPECT_GT(r.training_volumes, 10);
  EXPECT_TRUE(fs::exists(r.detector_file));
  // No test patient among the training ones.
  for (const auto& id : r.training_patients)
    for (const auto& run : r.runs) EXPECT_NE(id, run.id);

  const json j = json::parse(std::ifstream(o.out / "study.json"));
  EXPECT_EQ(j.at("format"), "mvtwin-detection-study");
  EXPECT_EQ(j.at("synthetic"), true);
  EXPECT_EQ(j.at("runs").size(), 2u);
  EXPECT_TRUE(j.at("provenance").contains("mvtwin_version"));
  // study.h5: one row per detected frame, the surface error where the frame has one.
  const TableFile t = read_table_file(o.out / "study.h5");
  std::size_t frames = 0;
  for (const auto& run : r.runs) frames += run.frames.size();
  ASSERT_FALSE(t.columns.empty());
  EXPECT_EQ(t.columns.front().strings.size(), frames);
  for (const char* f : {"report.md", "report.html", "noise_curve.png", "error_over_cycle.png"})
    EXPECT_TRUE(fs::exists(o.out / f)) << f;

  // Rerun with a third, much noisier level: the first two are resumed, not redone (not even
  // the training), and images buried in noise are detected worse.
  int resumed = 0, trained = 0;
  o.noise_levels = {0.004, 0.1, 3.0};
  o.progress = [&](const StudyEvent& e) {
    resumed += e.stage == "detect" && e.message.find("resumed") != std::string::npos;
    trained += e.stage == "train" && e.message.find("trained in") != std::string::npos;
  };
  const DetectionStudyResult r2 = run_detection_study(o, *pool);
  EXPECT_EQ(resumed, 2);
  EXPECT_EQ(trained, 0);
  ASSERT_EQ(r2.curve.size(), 3u);
  EXPECT_EQ(r2.curve[0]["error_mean_mm"], r.curve[0]["error_mean_mm"]);
  EXPECT_GT(r2.curve[2]["error_mean_mm"].get<double>(), e0);

  // A detection redone from scratch gives the same errors (same seed, same result). Not under
  // ASan: the same code as the first detection, and this test is the ASan run's longest.
#ifndef __SANITIZE_ADDRESS__
  fs::remove(o.out / "records" / "detect_0000_noise_0.1.json");
  const DetectionStudyResult r3 = run_detection_study(o, *pool);
  ASSERT_EQ(r3.runs.size(), 3u);
  const json& a = r2.runs[1].frames;
  const json& b = r3.runs[1].frames;
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t f = 0; f < a.size(); ++f) {
    EXPECT_EQ(a[f].value("surface_error_mm", -1.0), b[f].value("surface_error_mm", -1.0)) << f;
    EXPECT_EQ(a[f]["landmark_error_mm"], b[f]["landmark_error_mm"]) << f;
  }
#endif

  // A model that saw a test patient is refused, naming the patient.
  const fs::path leaky = dir_ / "leaky.yml.gz";
  detection::ValveDetector::load(r.detector_file)
      .save(leaky, {{"training_patients", r.runs[0].id + ",virtual-1 (synthetic)"}});
  DetectionStudyOptions given = quick("given");
  given.model_file = leaky;
  try {
    run_detection_study(given, *pool);
    FAIL() << "a model trained on a test patient was used";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(r.runs[0].id), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(given.out));  // refused before anything was written
}

}  // namespace
