// The robustness study: abused inputs end as converged runs or clean failures with a reason,
// never a crash or NaN; cases do not depend on the number of runs or on who runs them.
#include "mvtwin/studies/robustness_study.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "mvtwin/core/error.h"
#include "mvtwin/core/outcome.h"
#include "mvtwin/core/table_file.h"

namespace fs = std::filesystem;
using namespace mvtwin;
using namespace mvtwin::studies;

namespace {

TEST(RobustnessStudy, QuickStudyClassifiesEveryCaseAndExtendsWithMoreRuns) {
  const fs::path dir = fs::temp_directory_path() / ("mvtwin_rob_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  RobustnessStudyOptions o = RobustnessStudyOptions::quick();
  o.out = dir;
  o.runs = 8;
  auto pool = make_local_pool();
  const RobustnessStudyResult r = run_robustness_study(o, *pool);
  ASSERT_EQ(r.cases.size(), 8u);
  EXPECT_EQ(r.converged + r.clean_failures + r.crashes + r.nonfinite, 8);
  EXPECT_EQ(r.crashes, 0);
  EXPECT_EQ(r.nonfinite, 0);
  EXPECT_GT(r.converged, 0);  // abuse, but most inputs are still a valve that closes
  for (const auto& c : r.cases) {
    EXPECT_TRUE(c.dt >= 0.001 && c.dt <= 0.1) << c.dt;
    EXPECT_TRUE(c.peak_pressure_mmhg >= 0 && c.peak_pressure_mmhg <= 200);
    if (c.outcome == "clean_failure") {
      EXPECT_FALSE(c.reason.empty()) << c.index;
      // Classified by the simulator's typed outcome, never by the message's words.
      const std::optional<Outcome> kind = parse_outcome(c.failure_kind);
      ASSERT_TRUE(kind.has_value()) << c.failure_kind;
      EXPECT_NE(*kind, Outcome::kConverged);
    } else {
      EXPECT_TRUE(c.failure_kind.empty()) << c.index;
    }
  }
  std::ifstream f(dir / "study.json");
  const nlohmann::json j = nlohmann::json::parse(f);
  EXPECT_EQ(j.at("format"), "mvtwin-robustness-study");
  EXPECT_EQ(j.at("cases").size(), 8u);
  EXPECT_EQ(read_table_file(dir / "study.h5").columns.front().strings.size(), 8u);
  EXPECT_GT(fs::file_size(dir / "report.html"), 1000u);

  // More runs in the same folder: the first 8 are resumed, unchanged; only the new ones run.
  int resumed = 0;
  o.runs = 10;
  o.progress = [&](const StudyEvent& e) {
    resumed += e.message.find("resumed") != std::string::npos;
  };
  const RobustnessStudyResult more = run_robustness_study(o, *pool);
  EXPECT_EQ(resumed, 8);
  ASSERT_EQ(more.cases.size(), 10u);
  for (int i = 0; i < 8; ++i) {
    EXPECT_EQ(more.cases[i].dt, r.cases[i].dt);
    EXPECT_EQ(more.cases[i].outcome, r.cases[i].outcome);
  }
  // Case 9 run again (its record lost) is the same case: its draws depend on its index only.
  fs::remove(dir / "records" / "case_9.json");
  resumed = 0;
  const RobustnessStudyResult again = run_robustness_study(o, *pool);
  EXPECT_EQ(resumed, 9);
  EXPECT_EQ(again.cases[9].dt, more.cases[9].dt);
  EXPECT_EQ(again.cases[9].patient_seed, more.cases[9].patient_seed);
  EXPECT_EQ(again.cases[9].outcome, more.cases[9].outcome);
  fs::remove_all(dir);
}

}  // namespace
