// The clip study: every scenario of every patient simulated, the best single clip and pair found
// among them, clips that hold (small gaps) and reduce the orifice, resumable.
#include "mvtwin/studies/clip_study.h"

#include <unistd.h>

#include <algorithm>
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

TEST(ClipStudy, CandidatesAreSinglesThenPairsFarEnoughApart) {
  ClipStudyOptions o;
  const auto c = o.candidates();
  // 7 singles and the 15 pairs of 0.2..0.8 at least 0.2 apart (21 pairs less the 6 neighbours).
  ASSERT_EQ(c.size(), 22u);
  for (std::size_t i = 0; i < 7; ++i) EXPECT_EQ(c[i].size(), 1u);
  for (std::size_t i = 7; i < c.size(); ++i) {
    ASSERT_EQ(c[i].size(), 2u);
    EXPECT_GE(c[i][1] - c[i][0], 0.2 - 1e-9);
  }
  o.pairs = false;
  EXPECT_EQ(o.candidates().size(), 7u);
}

TEST(ClipStudy, QuickStudyFindsTheBestClipsAndResumes) {
  const fs::path dir = fs::temp_directory_path() / ("mvtwin_clip_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  ClipStudyOptions o = ClipStudyOptions::quick();
  o.out = dir;
  auto pool = make_local_pool();
  const ClipStudyResult r = run_clip_study(o, *pool);
  ASSERT_EQ(r.patients.size(), 2u);
  const std::size_t per = o.candidates().size() + 1;
  for (const auto& p : r.patients) {
    ASSERT_EQ(p.status, "ok") << p.id << ": " << p.reason;
    EXPECT_TRUE(p.synthetic);
    ASSERT_EQ(p.scenarios.size(), per);
    EXPECT_TRUE(p.scenarios.front().positions.empty());
    EXPECT_EQ(p.scenarios.front().max_clip_gap_mm, 0.0);
    for (const auto& s : p.scenarios) ASSERT_EQ(s.status, "ok") << p.id << ": " << s.reason;
    // The best single clip is the smallest orifice among the single clips.
    ASSERT_GE(p.best_single, 1);
    ASSERT_GE(p.best_pair, 1);
    for (const auto& s : p.scenarios) {
      if (s.positions.size() == 1) {
        EXPECT_LE(p.scenarios[p.best_single].orifice_mm2, s.orifice_mm2);
      }
      // A clip holds its leaflets together: the atrial surfaces end about a leaflet thickness
      // apart, never the centimetres of an open valve.
      if (!s.positions.empty()) {
        EXPECT_GT(s.max_clip_gap_mm, 0.0);
        EXPECT_LT(s.max_clip_gap_mm, 3.0);
      }
    }
    EXPECT_EQ(p.scenarios[p.best_pair].positions.size(), 2u);
    EXPECT_EQ(p.two_clips_win, p.scenarios[p.best_pair].orifice_mm2 <=
                                   p.scenarios[p.best_single].orifice_mm2 - o.two_clip_margin_mm2);
  }
  // The valve that leaks most (here an unsatisfactory closure, over 5 mm^2) leaks less once
  // clipped: the clip joins the leaflets where they fail to meet. (A valve that already closes
  // may leak more: a clip can split a closed line into openings beside it.)
  const auto& worst = *std::max_element(r.patients.begin(), r.patients.end(), [](auto& a, auto& b) {
    return a.scenarios.front().orifice_mm2 < b.scenarios.front().orifice_mm2;
  });
  ASSERT_GT(worst.scenarios.front().orifice_mm2, 5.0);
  EXPECT_LT(worst.scenarios[worst.best_single].orifice_mm2, worst.scenarios.front().orifice_mm2);
  EXPECT_LT(std::min(worst.scenarios[worst.best_single].orifice_mm2,
                     worst.scenarios[worst.best_pair].orifice_mm2),
            0.9 * worst.scenarios.front().orifice_mm2);
  std::ifstream f(dir / "study.json");
  const nlohmann::json j = nlohmann::json::parse(f);
  EXPECT_EQ(j.at("format"), "mvtwin-clip-study");
  ASSERT_EQ(j.at("patients").size(), 2u);
  EXPECT_TRUE(j.at("patients")[0].at("orifice_best_single_mm2").is_number());
  EXPECT_EQ(j.at("summary").at("overall").at("patients"), 2);
  const TableFile t = read_table_file(dir / "study.h5");
  EXPECT_EQ(t.columns.front().strings.size(), 2 * per);
  EXPECT_GT(fs::file_size(dir / "orifice.png"), 1000u);
  EXPECT_GT(fs::file_size(dir / "report.html"), 1000u);

  int resumed = 0;
  o.progress = [&](const StudyEvent& e) {
    resumed += e.message.find("resumed") != std::string::npos;
  };
  const ClipStudyResult again = run_clip_study(o, *pool);
  EXPECT_EQ(resumed, static_cast<int>(2 * per));
  EXPECT_EQ(again.patients[1].scenarios[2].orifice_mm2, r.patients[1].scenarios[2].orifice_mm2);
  fs::remove_all(dir);
}

TEST(ClipStudy, BadPatientFileIsRecordedAndTheStudyGoesOn) {
  const fs::path dir = fs::temp_directory_path() / ("mvtwin_clipbad_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "patients");
  std::ofstream(dir / "patients" / "broken.h5") << "not hdf5";
  ClipStudyOptions o = ClipStudyOptions::quick();
  o.out = dir / "out";
  o.folder = dir / "patients";
  o.pairs = false;
  auto pool = make_local_pool();
  const ClipStudyResult r = run_clip_study(o, *pool);
  ASSERT_EQ(r.patients.size(), 1u);
  EXPECT_EQ(r.patients[0].status, "failed");
  EXPECT_NE(r.patients[0].reason.find("broken.h5"), std::string::npos) << r.patients[0].reason;
  EXPECT_EQ(r.summary.at("overall").at("failed"), 1);
  EXPECT_TRUE(fs::exists(o.out / "report.md"));
  fs::remove_all(dir);
}

TEST(ClipStudy, InvalidOptionsAreRefused) {
  ClipStudyOptions o = ClipStudyOptions::quick();
  o.out = "x";
  std::string e;
  ClipStudyOptions b = o;
  b.positions = {0.5, 1.2};
  EXPECT_FALSE(b.is_valid(&e));
  EXPECT_NE(e.find("positions"), std::string::npos) << e;
  b = o;
  b.positions = {0.45, 0.5};
  b.pair_spacing = 0.2;
  EXPECT_FALSE(b.is_valid(&e));  // pairs asked for, none possible
  EXPECT_NE(e.find("no pairs"), std::string::npos) << e;
  b = o;
  b.two_clip_margin_mm2 = -1;
  EXPECT_FALSE(b.is_valid(&e));
  EXPECT_TRUE(o.is_valid(&e)) << e;
}

}  // namespace
