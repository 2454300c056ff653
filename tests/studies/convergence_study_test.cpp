// The convergence study: the runs of every series measured against the series' finest run, the
// base model simulated once, errors that shrink as the time step does, resumable.
#include "mvtwin/studies/convergence_study.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "mvtwin/core/error.h"
#include "mvtwin/core/table_file.h"

namespace fs = std::filesystem;
using namespace mvtwin;
using namespace mvtwin::studies;

namespace {

const ConvergenceRun& find(const ConvergenceStudyResult& r, const std::string& factor,
                           const std::string& value) {
  for (const auto& k : r.runs)
    if (k.factor == factor && k.value == value) return k;
  throw Error("no run " + factor + "=" + value);
}

TEST(ConvergenceStudy, QuickStudyMeasuresEachSeriesAgainstItsFinestRunAndResumes) {
  const fs::path dir = fs::temp_directory_path() / ("mvtwin_conv_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  ConvergenceStudyOptions o = ConvergenceStudyOptions::quick();
  o.out = dir;
  auto pool = make_local_pool();
  int simulated = 0;
  o.progress = [&](const StudyEvent& e) {
    simulated += e.message.find("resumed") == std::string::npos;
  };
  const ConvergenceStudyResult r = run_convergence_study(o, *pool);
  const std::size_t runs = o.ures.size() + o.vres.size() + o.layers.size() + o.dt.size();
  ASSERT_EQ(r.runs.size(), runs);
  // The base model (12 x 8, 1 layer, dt 0.02) is in all four series and simulated once.
  // Each distinct model is paired with its static solve: twice as many simulations.
  EXPECT_EQ(r.simulations, 2 * (static_cast<int>(runs) - 3));
  EXPECT_EQ(simulated, r.simulations);
  EXPECT_TRUE(r.synthetic);
  for (const auto& k : r.runs) {
    ASSERT_EQ(k.status, "ok") << k.factor << "=" << k.value << ": " << k.reason;
    if (k.reference) {
      EXPECT_NEAR(k.error_mean_mm, 0.0, 1e-9) << k.factor;  // against itself
      EXPECT_NEAR(k.error_max_mm, 0.0, 1e-9) << k.factor;
    } else {
      EXPECT_GT(k.error_mean_mm, 1e-4) << k.factor << "=" << k.value;
      EXPECT_GE(k.error_max_mm, k.error_p95_mm);
      EXPECT_GE(k.error_p95_mm, k.error_mean_mm);
    }
  }
  // The same model gives the same run whatever series it stands in.
  EXPECT_EQ(find(r, "ures", "12").wall_s, find(r, "dt", "0.02").wall_s);
  EXPECT_EQ(find(r, "ures", "12").dofs, find(r, "vres", "8").dofs);
  // Finer models have more unknowns; smaller steps take more steps.
  EXPECT_GT(find(r, "ures", "16").dofs, find(r, "ures", "12").dofs);
  EXPECT_GT(find(r, "layers", "2").dofs, find(r, "layers", "1").dofs);
  EXPECT_GT(find(r, "dt", "0.01").steps, find(r, "dt", "0.02").steps);
  // Time convergence: halving the step brings the closed surface closer to the finest one.
  EXPECT_GT(find(r, "dt", "0.04").error_mean_mm, find(r, "dt", "0.02").error_mean_mm);
  // Paired (static_rest=on by default): every model again, brought to rest by the static solve,
  // against the same references; the same model pairs alike in every series, and the static
  // end of a model is near its settled end (both are the valve at rest) but not the same run.
  for (const auto& k : r.runs) {
    ASSERT_EQ(k.paired_status, "ok") << k.factor << "=" << k.value << ": " << k.paired_reason;
    EXPECT_TRUE(std::isfinite(k.paired_error_mean_mm)) << k.factor << "=" << k.value;
    EXPECT_GT(k.paired_difference_mm, 0.0) << k.factor << "=" << k.value;
    EXPECT_LT(k.paired_difference_mm, 0.25) << k.factor << "=" << k.value;
  }
  EXPECT_EQ(find(r, "ures", "12").paired_wall_s, find(r, "dt", "0.02").paired_wall_s);
  EXPECT_NEAR(find(r, "ures", "16").paired_error_mean_mm,
              find(r, "ures", "16").paired_difference_mm, 1e-12)
      << "the reference's own pair: its error is its distance from the reference";

  std::ifstream f(dir / "study.json");
  const nlohmann::json j = nlohmann::json::parse(f);
  EXPECT_EQ(j.at("format"), "mvtwin-convergence-study");
  EXPECT_EQ(j.at("runs").size(), runs);
  EXPECT_TRUE(j.at("runs")[0].at("error_mean_mm").is_number());
  EXPECT_TRUE(j.at("runs")[0].at("paired").at("error_mean_mm").is_number());
  EXPECT_EQ(j.at("config").at("pair"), nlohmann::json::array({"static_rest=on"}));
  const TableFile t = read_table_file(dir / "study.h5");
  EXPECT_EQ(t.columns.front().strings.size(), runs);
  for (const char* png : {"convergence_ures.png", "convergence_dt.png", "pareto.png"})
    EXPECT_GT(fs::file_size(dir / png), 1000u) << png;
  EXPECT_GT(fs::file_size(dir / "report.html"), 1000u);

  // Resumed: nothing simulated again, the same errors.
  simulated = 0;
  const ConvergenceStudyResult again = run_convergence_study(o, *pool);
  EXPECT_EQ(simulated, 0);
  for (std::size_t i = 0; i < runs; ++i)
    EXPECT_EQ(again.runs[i].error_mean_mm, r.runs[i].error_mean_mm) << i;

  // Another configuration in the same folder is refused, not mixed in.
  ConvergenceStudyOptions other = o;
  other.dt = {0.04, 0.01};
  EXPECT_THROW(run_convergence_study(other, *pool), Error);
  fs::remove_all(dir);
}

TEST(ConvergenceStudy, InvalidSeriesAreRefused) {
  auto pool = make_local_pool();
  ConvergenceStudyOptions o = ConvergenceStudyOptions::quick();
  EXPECT_THROW(run_convergence_study(o, *pool), Error);  // no --out
  o.out = fs::temp_directory_path() / "mvtwin_conv_invalid";
  auto refused = [&](ConvergenceStudyOptions bad, const std::string& words) {
    std::string e;
    EXPECT_FALSE(bad.is_valid(&e));
    EXPECT_NE(e.find(words), std::string::npos) << e;
  };
  ConvergenceStudyOptions b = o;
  b.ures = {16, 12};
  refused(b, "increase");
  b = o;
  b.dt = {0.01, 0.02};
  refused(b, "decrease");
  b = o;
  b.layers = {1};
  refused(b, "at least two");
  b = o;
  b.dt = {0.02, -0.01};
  refused(b, "dt");
  b = o;
  b.pair = {"static_rest=maybe"};
  refused(b, "paired run");
  b.pair = {"no_such_option=1"};
  refused(b, "no_such_option");
  EXPECT_FALSE(fs::exists(o.out));  // nothing written for refused options
}

}  // namespace
