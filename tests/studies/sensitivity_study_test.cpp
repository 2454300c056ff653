// The sensitivity study: every case simulated, differences measured against the baseline, the
// paper's ordering of effects (rest lengths move the tips far more than chordae stiffness).
#include "mvtwin/studies/sensitivity_study.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "mvtwin/core/error.h"
#include "mvtwin/core/table_file.h"

namespace fs = std::filesystem;
using namespace mvtwin;
using namespace mvtwin::studies;

namespace {

const SensitivityCase& find(const SensitivityStudyResult& r, const std::string& label) {
  for (const auto& k : r.cases)
    if (k.label == label) return k;
  throw Error("no case " + label);
}

TEST(SensitivityStudy, QuickStudyMeasuresEveryCaseAgainstTheBaselineAndResumes) {
  const fs::path dir = fs::temp_directory_path() / ("mvtwin_sens_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  SensitivityStudyOptions o = SensitivityStudyOptions::quick();
  o.out = dir;
  auto pool = make_local_pool();
  const SensitivityStudyResult r = run_sensitivity_study(o, *pool);
  ASSERT_EQ(r.cases.size(), sensitivity_cases().size());
  EXPECT_TRUE(r.synthetic);
  for (const auto& k : r.cases) {
    EXPECT_EQ(k.status, "ok") << k.label << ": " << k.reason;
    ASSERT_GT(k.time_s.size(), 5u) << k.label;  // a curve over time, not only the end
    EXPECT_EQ(k.time_s.size(), k.anterior_tip_mm.size());
    EXPECT_TRUE(std::is_sorted(k.time_s.begin(), k.time_s.end()));
  }
  EXPECT_EQ(r.cases.front().label, "baseline");
  EXPECT_DOUBLE_EQ(r.cases.front().max_anterior_diff_mm, 0.0);
  EXPECT_DOUBLE_EQ(r.cases.front().max_posterior_diff_mm, 0.0);
  // Every change moves the tips somewhat; the time series start at the same open state.
  for (const auto& k : r.cases) {
    if (k.label == "baseline") continue;
    EXPECT_GT(std::max(k.max_anterior_diff_mm, k.max_posterior_diff_mm), 0.01) << k.label;
    EXPECT_NEAR(k.anterior_tip_mm.front(), r.cases.front().anterior_tip_mm.front(), 1e-9)
        << k.label;
  }
  // The paper's finding (Sec. 4.2): rest lengths +-30 % matter far more than stiffness +-30 %.
  for (const char* rl : {"rest lengths -30 %", "rest lengths +30 %"})
    for (const char* st : {"stiffness -30 %", "stiffness +30 %"})
      EXPECT_GT(find(r, rl).max_anterior_diff_mm, 3.0 * find(r, st).max_anterior_diff_mm)
          << rl << " vs " << st;
  // Shorter chordae hold the anterior tip further into the ventricle.
  EXPECT_LT(find(r, "rest lengths -30 %").end_anterior_tip_mm, r.cases.front().end_anterior_tip_mm);
  EXPECT_GT(find(r, "rest lengths +30 %").end_anterior_tip_mm, r.cases.front().end_anterior_tip_mm);

  const TableFile t = read_table_file(dir / "study.h5");
  EXPECT_EQ(t.columns.front().strings.size(), r.cases.size());
  EXPECT_GT(fs::file_size(dir / "al_rest_length.png"), 1000u);
  EXPECT_GT(fs::file_size(dir / "report.html"), 1000u);

  // Resumed: nothing simulated again, the same curves.
  int resumed = 0;
  o.progress = [&](const StudyEvent& e) {
    resumed += e.message.find("resumed") != std::string::npos;
  };
  const SensitivityStudyResult again = run_sensitivity_study(o, *pool);
  EXPECT_EQ(resumed, static_cast<int>(r.cases.size()));
  EXPECT_EQ(again.cases[3].anterior_tip_mm, r.cases[3].anterior_tip_mm);
  fs::remove_all(dir);
}

TEST(SensitivityStudy, InvalidOptionsAreRefused) {
  auto pool = make_local_pool();
  SensitivityStudyOptions o = SensitivityStudyOptions::quick();
  EXPECT_THROW(run_sensitivity_study(o, *pool), Error);  // no --out
  o.out = fs::temp_directory_path() / "mvtwin_sens_invalid";
  o.sample_s = 0;
  EXPECT_THROW(run_sensitivity_study(o, *pool), Error);
  o.sample_s = 0.01;
  o.model.dt = -1;
  EXPECT_THROW(run_sensitivity_study(o, *pool), Error);
}

}  // namespace
