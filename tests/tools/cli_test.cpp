// End-to-end tests of the mvtwin command line, run as a user would.
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "mvtwin/core/patient_file.h"

namespace {

namespace fs = std::filesystem;

struct CmdResult {
  int code;
  std::string out, err;
};

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("mvtwin_cli_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  CmdResult run(const std::string& args) {
    const std::string o = (dir_ / "stdout.txt").string(), e = (dir_ / "stderr.txt").string();
    const std::string cmd = std::string(MVTWIN_BINARY) + " " + args + " > " + o + " 2> " + e;
    const int status = std::system(cmd.c_str());
    auto slurp = [](const std::string& p) {
      std::ifstream f(p);
      std::stringstream s;
      s << f.rdbuf();
      return s.str();
    };
    return {WEXITSTATUS(status), slurp(o), slurp(e)};
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST_F(Cli, EveryCommandHelpShowsARealInvocation) {
  for (const char* c : {"phantom", "cohort", "info", "export", "import-seg", "distance", "export-model", "simulate",
                        "calibrate", "clip"}) {
    const CmdResult r = run(std::string(c) + " --help");
    EXPECT_EQ(r.code, 0) << c;
    EXPECT_NE(r.out.find(std::string("mvtwin ") + c + " "), std::string::npos) << c << ":\n"
                                                                               << r.out;
  }
}

TEST_F(Cli, PhantomInfoExport) {
  CmdResult r = run("phantom --seed 4 --out " + path("p.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("SYNTHETIC"), std::string::npos);
  r = run("info " + path("p.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("[SYNTHETIC: virtual patient]"), std::string::npos);
  EXPECT_NE(r.out.find("end-diastole (frame"), std::string::npos);
  EXPECT_NE(r.out.find("hidden    pathology"), std::string::npos);
  r = run("export-model " + path("p.h5") + " --out " + path("model") + " --ures 12 --vres 6");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir_ / "model" / "leaflets.vtu"));
  EXPECT_TRUE(fs::exists(dir_ / "model" / "chordae.vtp"));
  r = run("export " + path("p.h5") + " --vtk " + path("vtk"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir_ / "vtk" / "la_surface.pvd"));
  // Refuses to overwrite without --force; nothing is lost.
  r = run("phantom --seed 5 --out " + path("p.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("already exists"), std::string::npos);
  EXPECT_EQ(mvtwin::read_patient(path("p.h5")).provenance.seed, 4u);
  // Same seed, same result.
  ASSERT_EQ(run("phantom --seed 4 --out " + path("q.h5")).code, 0);
  const auto a = mvtwin::read_patient(path("p.h5")), b = mvtwin::read_patient(path("q.h5"));
  EXPECT_EQ(a.sequence.frames[0].la_surface->points(), b.sequence.frames[0].la_surface->points());
}

TEST_F(Cli, BadInputGivesAClearErrorAndNonZeroExit) {
  CmdResult r = run("info " + path("missing.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("missing.h5: no such file"), std::string::npos) << r.err;
  { std::ofstream(path("junk.h5")) << "junk"; }
  r = run("info " + path("junk.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("not an HDF5 file"), std::string::npos) << r.err;
  r = run("phantom --seed 1 --ures 9 --out " + path("x.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("ures must be even"), std::string::npos) << r.err;
  r = run("phantom --pathology flu --out " + path("x.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("unknown pathology 'flu'"), std::string::npos) << r.err;
  r = run("import-seg " + path("none.nii.gz") + " --out " + path("x.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("none.nii.gz: no such file"), std::string::npos) << r.err;
  r = run("frobnicate");
  EXPECT_NE(r.code, 0);
  EXPECT_FALSE(fs::exists(dir_ / "x.h5"));
}

TEST_F(Cli, CalibrateAndClipRefuseWhatTheyCannotUse) {
  ASSERT_EQ(run("phantom --seed 4 --out " + path("p.h5")).code, 0);
  // No observed closed valve (closing frames not simulated): named, nothing written.
  CmdResult r = run("calibrate " + path("p.h5") + " --out " + path("c.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--simulate-closure"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("c.h5")));
  r = run("calibrate " + path("p.h5") + " --fit restlength,viscosity --out " + path("c.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("'viscosity'"), std::string::npos) << r.err;
  r = run("clip " + path("p.h5") + " --at 1.5,1");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("position 1.5"), std::string::npos) << r.err;
  r = run("clip " + path("p.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--at"), std::string::npos) << r.err;
  r = run("clip " + path("p.h5") + " --params " + path("p.h5") + " --at 0.5");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("not an mvtwin calibration file"), std::string::npos) << r.err;
}

TEST_F(Cli, DetectionFromSyntheticTeeAndItsBenchmark) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "simulating, rendering and training forests takes too long under AddressSanitizer";
#endif
  // Refusals first: nothing to train on; both sources at once.
  CmdResult r = run("train-detector --out " + path("m.yml.gz"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--cohort DIR or --virtual N"), std::string::npos) << r.err;
  r = run("train-detector --virtual 3 --cohort " + path("") + " --out " + path("m.yml.gz"));
  EXPECT_NE(r.code, 0);
  EXPECT_FALSE(fs::exists(dir_ / "m.yml.gz"));
  r = run("clip " + path("p.h5") + " --true-params --params " + path("c.h5") + " --at 0.5");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("excludes"), std::string::npos) << r.err;

  // A small virtual training cohort (coarse voxels, small forests), its truths cached.
  const std::string small =
      " --voxel 2.5 --trees 8 --samples 300 --jobs 2 --truth-set ures=16 --truth-set vres=8 --train-noise 0.004"
      " --cache " + path("cache");
  r = run("train-detector --virtual 3 --cohort-seed 77 --out " + path("m.yml.gz") + small);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("training on "), std::string::npos) << r.out;
  ASSERT_TRUE(fs::exists(dir_ / "m.yml.gz"));
  {
    std::ifstream f(path("m.yml.gz"));
    EXPECT_TRUE(f.good());
  }
  // The benchmark of that model on one held-out patient (its truth cached beside the others);
  // its figures say what made them.
  const std::string bench = "bench detect --model " + path("m.yml.gz") +
                            " --test 1 --seed 77 --noise-levels 0.004,0.1 --json " + path("d.json") + small;
  r = run(bench);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  std::ifstream f(path("d.json"));
  std::stringstream js;
  js << f.rdbuf();
  const std::string j = js.str();
  for (const char* key : {"\"error_mean_mm\"", "\"error_sd_mm\"", "\"landmark_error_mm\"", "\"papillary_error_mm\"",
                          "\"s_per_volume\"", "\"n_train\": 3", "\"n_test\": 1", "\"noise_levels\"",
                          "\"posteromedial_papillary_tip\"", "\"synthetic\": true", "\"mvtwin_version\""})
    EXPECT_NE(j.find(key), std::string::npos) << key << " missing from\n" << j.substr(0, 2000);
  EXPECT_NE(r.out.find("patient 1/1"), std::string::npos) << r.out;
  // Run again: everything is resumed from the JSON, nothing is detected twice.
  r = run(bench);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("resuming: 2 detections"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("patient 1/1"), std::string::npos) << r.out;
}

TEST_F(Cli, CohortResumesAndSurvivesADamagedFile) {
  CmdResult r = run("cohort --n 4 --seed 3 --out " + path("c"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("made 4, kept 0, failed 0"), std::string::npos) << r.out;
  const auto before = mvtwin::read_patient(path("c/patient_0002.h5"));
  fs::remove(dir_ / "c" / "patient_0001.h5");
  { std::ofstream(path("c/patient_0003.h5")) << "damaged"; }
  r = run("cohort --n 4 --seed 3 --out " + path("c"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("made 2, kept 2, failed 0"), std::string::npos) << r.out;
  EXPECT_NO_THROW(mvtwin::read_patient(path("c/patient_0003.h5")));
  const auto after = mvtwin::read_patient(path("c/patient_0002.h5"));
  EXPECT_EQ(before.provenance.created_utc, after.provenance.created_utc);  // kept, not remade
  EXPECT_TRUE(fs::exists(dir_ / "c" / "cohort.json"));
}

TEST_F(Cli, ImportRealSegmentation) {
  const fs::path seg = fs::path(MVTWIN_SHARED_DATA_DIR) / "mvtool-008" / "008_gt.nii.gz";
  if (!fs::exists(seg))
    GTEST_SKIP() << "../shared/data absent (a user's clone has no ../shared): skipped";
  CmdResult r = run("import-seg " + seg.string() + " --out " + path("008.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("fitted surface -> mask boundary"), std::string::npos);
  r = run("info " + path("008.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out.find("SYNTHETIC"), std::string::npos);  // real data is never labelled synthetic
  const fs::path pred = seg.parent_path() / "008_pred.nii.gz";
  ASSERT_EQ(run("import-seg " + pred.string() + " --out " + path("pred.h5")).code, 0);
  r = run("distance " + path("008.h5") + " " + path("pred.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("symmetric: "), std::string::npos);
  // A surface against itself is at distance zero.
  r = run("distance " + path("008.h5") + " " + path("008.h5"));
  EXPECT_NE(r.out.find("symmetric: 0.00 +- 0.00 mm"), std::string::npos) << r.out;
  r = run("import-seg " + seg.string() + " --labels 1,2,9 --out " + path("bad.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("label 9 (posterior leaflet) has 0 voxels"), std::string::npos) << r.err;
}

}  // namespace
