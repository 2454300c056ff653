// The clip prediction study: qualifying patients found by their observed EROA, every option's
// truth (fine model, hidden parameters), prediction (calibrated, with intervals) and baseline
// (defaults) recorded, ranks and the summary's counts consistent with them, resumable.
#include "mvtwin/studies/clip_study.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "mvtwin/core/calibration_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/table_file.h"

namespace fs = std::filesystem;
using namespace mvtwin;
using namespace mvtwin::studies;

namespace {

bool within(double p, double t, double a, double r) {
  return std::abs(p - t) <= std::max(a, r * std::abs(t));
}

}  // namespace

TEST(ClipStudy, QuickStudyComparesPredictionsWithTheTruthAndResumes) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "two calibrations and a dozen closures take many minutes under "
                  "AddressSanitizer (the observation, calibration, clip and diastole run under it "
                  "in their own tests)";
#endif
  const fs::path dir = fs::temp_directory_path() / ("mvtwin_clip_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  ClipStudyOptions o = ClipStudyOptions::quick();
  o.out = dir / "study";
  o.positions = {0.4, 0.6};  // two options: ranks mean something
  auto pool = make_local_pool();
  const ClipStudyResult r = run_clip_study(o, *pool);
  ASSERT_EQ(r.patients.size(), 2u);
  ASSERT_EQ(r.scanned.size(), 2u);  // no threshold: the first two members
  int in_eroa = 0, n_eroa = 0, in_default = 0, opened = 0, diastoles = 0;
  for (const auto& p : r.patients) {
    ASSERT_EQ(p.status, "ok") << p.id << ": " << p.reason;
    // The truth without a clip is the observed closure's orifice.
    EXPECT_TRUE(std::isfinite(p.eroa_no_clip_true_mm2));
    // The calibration fitted and improved the fit to the observed frames.
    EXPECT_LT(p.error_after_mm, p.error_before_mm) << p.id;
    EXPECT_TRUE(fs::exists(o.out / "calibrations" / (p.id + ".h5"))) << p.id;
    const CalibrationRecord cal = read_calibration_file(o.out / "calibrations" / (p.id + ".h5"));
    EXPECT_EQ(cal.patient_id, p.id);
    ASSERT_EQ(p.options.size(), 2u);
    double lowest_true = 1e9, lowest_pred = 1e9;
    for (const auto& op : p.options) {
      EXPECT_EQ(op.device, "XTW");
      ASSERT_TRUE(std::isfinite(op.eroa_true_mm2)) << op.truth_reason;
      ASSERT_TRUE(std::isfinite(op.eroa_predicted_mm2)) << op.prediction_reason;
      ASSERT_TRUE(std::isfinite(op.eroa_default_mm2));
      // Every clipped valve opens (with the diastole's contact as soft as its few mmHg, 3 of
      // these 8 failed in the clip phase, docs/clip-devices.md); a failure would be kept with
      // its reason.
      for (const auto& [mva, reason] : {std::pair{op.mva_true_cm2, op.truth_reason},
                                        std::pair{op.mva_predicted_cm2, op.prediction_reason}}) {
        EXPECT_TRUE(std::isfinite(mva) && mva > 0.0) << mva << ": " << reason;
        opened += std::isfinite(mva) && mva > 0.0;
        ++diastoles;
      }
      // An interval from the calibration's covariance.
      EXPECT_TRUE(std::isfinite(op.eroa_predicted_sd_mm2));
      EXPECT_GE(op.eroa_predicted_sd_mm2, 0.0);
      lowest_true = std::min(lowest_true, op.eroa_true_mm2);
      lowest_pred = std::min(lowest_pred, op.eroa_predicted_mm2);
    }
    // Rank 1 is the smallest EROA; the two ranks of a column differ.
    ASSERT_GE(p.best_true, 0);
    ASSERT_GE(p.best_predicted, 0);
    EXPECT_EQ(p.options[p.best_true].eroa_true_mm2, lowest_true);
    EXPECT_EQ(p.options[p.best_true].rank_true, 1);
    EXPECT_EQ(p.options[p.best_predicted].eroa_predicted_mm2, lowest_pred);
    EXPECT_NE(p.options[0].rank_true, p.options[1].rank_true);
    // The summary's counts, recomputed.
    auto count = [&](double pred, double def, double t) {
      ++n_eroa;
      in_eroa += within(pred, t, 3.0, 0.25);
      in_default += within(def, t, 3.0, 0.25);
    };
    count(p.eroa_no_clip_predicted_mm2, p.eroa_no_clip_default_mm2, p.eroa_no_clip_true_mm2);
    for (const auto& op : p.options)
      count(op.eroa_predicted_mm2, op.eroa_default_mm2, op.eroa_true_mm2);
  }
  EXPECT_EQ(opened, diastoles) << opened << " of " << diastoles << " clipped valves opened";
  EXPECT_EQ(r.summary.at("eroa_compared"), n_eroa);
  EXPECT_EQ(r.summary.at("eroa_within_tolerance"), in_eroa);
  EXPECT_EQ(r.summary.at("eroa_default_within_tolerance"), in_default);
  EXPECT_EQ(r.summary.at("patients_ranked"), 2);

  std::ifstream f(o.out / "study.json");
  const nlohmann::json j = nlohmann::json::parse(f);
  EXPECT_EQ(j.at("format"), "mvtwin-clip-study");
  ASSERT_EQ(j.at("patients").size(), 2u);
  for (const char* key : {"id", "pathology", "eroa_no_clip_true_mm2", "eroa_no_clip_predicted_mm2",
                          "best_true", "best_predicted", "options"})
    EXPECT_TRUE(j.at("patients")[0].contains(key)) << key;
  for (const char* key :
       {"device", "positions", "eroa_true_mm2", "eroa_predicted_mm2", "eroa_predicted_sd_mm2",
        "eroa_default_mm2", "mva_true_cm2", "mva_predicted_cm2", "gradient_predicted_mmhg",
        "stenosis_predicted", "rank_true", "rank_predicted"})
    EXPECT_TRUE(j.at("patients")[0].at("options")[0].contains(key)) << key;
  EXPECT_EQ(j.at("provenance").at("seed"), o.seed);
  const TableFile t = read_table_file(o.out / "study.h5");
  EXPECT_EQ(t.columns.front().strings.size(), 2u * 3u);  // no clip and two options each
  EXPECT_GT(fs::file_size(o.out / "eroa_predicted_vs_true.png"), 1000u);
  EXPECT_GT(fs::file_size(o.out / "report.html"), 1000u);
  // The report's option table says per option whether the truth lies inside the 95 % interval,
  // as often as the summary counts it, and the report sums the records' compute.
  {
    std::ifstream rf(o.out / "report.md");
    const std::string text((std::istreambuf_iterator<char>(rf)), std::istreambuf_iterator<char>());
    std::stringstream lines(text);
    std::string line;
    int inside = 0, rows = 0;
    bool in_options = false;
    while (std::getline(lines, line)) {
      if (line.rfind("## ", 0) == 0) in_options = line == "## Every option";
      if (!in_options || line.rfind("| virtual-", 0) != 0) continue;
      std::vector<std::string> cells;
      std::stringstream ls(line);
      std::string c;
      while (std::getline(ls, c, '|')) cells.push_back(c);
      ASSERT_GE(cells.size(), 7u) << line;
      ++rows;
      inside += cells[6] == " yes ";
    }
    EXPECT_EQ(rows, 4);
    EXPECT_EQ(inside, r.summary.at("truth_in_interval").get<int>());
    EXPECT_NE(text.find("Compute, summed over the records"), std::string::npos);
  }

  // Resumed: nothing simulated again, the same numbers.
  int resumed = 0;
  o.progress = [&](const StudyEvent& e) {
    resumed += e.message.find("resumed") != std::string::npos;
  };
  const ClipStudyResult again = run_clip_study(o, *pool);
  EXPECT_EQ(resumed, 2 + 2 * 3);  // two members, two predictions, four truths
  EXPECT_EQ(again.patients[1].options[1].eroa_predicted_mm2,
            r.patients[1].options[1].eroa_predicted_mm2);

  // A threshold no member reaches: the observations are reused (the cache), none qualifies.
  ClipStudyOptions strict = ClipStudyOptions::quick();
  strict.out = dir / "strict";
  strict.cache = o.out / "observed";
  strict.min_eroa_mm2 = 999.0;
  const ClipStudyResult none = run_clip_study(strict, *pool);
  EXPECT_TRUE(none.patients.empty());
  ASSERT_EQ(none.scanned.size(), 4u);  // max_scanned
  EXPECT_EQ(none.scanned[0].at("eroa_true_mm2"), r.patients[0].eroa_no_clip_true_mm2);
  EXPECT_EQ(none.scanned[0].at("observe_s"), 0.0);  // cached

  // Resumed from its records alone (another machine: no observations) with one truth missing:
  // that truth is redone on its patient's observation made again, and nothing else is.
  fs::remove_all(o.out / "observed");
  char missing[48];
  std::snprintf(missing, sizeof missing, "patient_%04d_true_1", r.patients[1].index);
  ASSERT_TRUE(fs::remove(o.out / "records" / (std::string(missing) + ".json")));
  resumed = 0;
  const ClipStudyResult redone = run_clip_study(o, *pool);
  EXPECT_EQ(resumed, 2 + 2 * 3 - 1);
  EXPECT_EQ(redone.patients[1].options[1].eroa_true_mm2, r.patients[1].options[1].eroa_true_mm2);
  EXPECT_EQ(redone.patients[1].options[1].mva_true_cm2, r.patients[1].options[1].mva_true_cm2);
  int observed_again = 0;
  for (const auto& e : fs::directory_iterator(o.out / "observed"))
    observed_again += e.path().filename().string().find(r.patients[1].id + "_") != std::string::npos
                          ? 1
                          : 100;  // another patient's observation: made needlessly
  EXPECT_EQ(observed_again, 1);
  fs::remove_all(dir);
}

TEST(ClipStudy, InvalidOptionsAreRefused) {
  ClipStudyOptions o = ClipStudyOptions::quick();
  o.out = "x";
  std::string e;
  EXPECT_TRUE(o.is_valid(&e)) << e;
  ClipStudyOptions b = o;
  b.positions = {0.5, 1.2};
  EXPECT_FALSE(b.is_valid(&e));
  EXPECT_NE(e.find("positions"), std::string::npos) << e;
  b = o;
  b.devices = {"XTW", "NoSuchClip"};
  EXPECT_FALSE(b.is_valid(&e));
  EXPECT_NE(e.find("NoSuchClip"), std::string::npos) << e;
  b = o;
  b.max_scanned = 1;
  EXPECT_FALSE(b.is_valid(&e));
  EXPECT_NE(e.find("max_scanned"), std::string::npos) << e;
  b = o;
  b.fit = "restlength,nonsense";
  EXPECT_FALSE(b.is_valid(&e));
  EXPECT_NE(e.find("nonsense"), std::string::npos) << e;
  b = o;
  b.min_eroa_mm2 = -1;
  EXPECT_FALSE(b.is_valid(&e));
  b = o;
  b.out.clear();
  EXPECT_FALSE(b.is_valid(&e));
  EXPECT_THROW(run_clip_study(b, *make_local_pool()), Error);
}

TEST(ClipStudy, AFolderCalibratedWithoutTheModulusScanIsRefused) {
  // The calibration's modulus scan changes every fit of the moduli, so it is part of the
  // configuration when they are fitted (and only then: the cohort studies that fit no modulus
  // keep their folders).
  ClipStudyOptions o;
  ASSERT_NE(o.fit.find("modulus"), std::string::npos);
  const nlohmann::json with = o.config();
  ASSERT_TRUE(with.contains("modulus_scan"));
  EXPECT_EQ(with["modulus_scan"].size(), 5u);
  o.fit = "restlength";
  EXPECT_FALSE(o.config().contains("modulus_scan"));
  o.fit = "restlength,pl_modulus_scale";
  EXPECT_TRUE(o.config().contains("modulus_scan"));

  const fs::path dir =
      fs::temp_directory_path() / ("mvtwin_clip_scan_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  nlohmann::json old{{"study", "clip-prediction"}, {"config", with}};
  old["config"].erase("modulus_scan");
  std::ofstream(dir / "study_config.json") << old.dump(1);
  ClipStudyOptions again;
  again.out = dir;
  auto pool = make_local_pool();
  try {
    run_clip_study(again, *pool);
    FAIL() << "a folder calibrated without the modulus scan was resumed";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("modulus_scan"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}
