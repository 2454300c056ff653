// End-to-end tests of the mvtwin command line, run as a user would.
#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "mvtwin/core/nifti.h"
#include "mvtwin/core/point_to_mesh_distance.h"
#include "mvtwin/core/surface_mesh_io.h"
#include "mvtwin/detection/segmentation_fit.h"

#include "mvtwin/core/calibration_file.h"
#include "mvtwin/core/patient_file.h"

namespace {

namespace fs = std::filesystem;
using mvtwin::ImageVolume;
using mvtwin::Landmark;
using mvtwin::LeafletGrid;
using mvtwin::Patient;
using mvtwin::symmetric_surface_distance;
using mvtwin::SymmetricDistance;

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
  // --quick simulates the closing frames on the coarse model, and says so.
  r = run("phantom --seed 4 --simulate-closure --quick --out " + path("quick.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("ures 20, vres 10, 1 layers, dt 0.01 s"), std::string::npos) << r.out;
  const auto quick = mvtwin::read_patient(path("quick.h5"));
  ASSERT_GE(quick.sequence.first_closed, 0);
  EXPECT_TRUE(quick.sequence.frames[quick.sequence.first_closed].la_surface.has_value());
  // distance --json gives the printed figures at full precision: the closed frame against the
  // open end-diastolic one (millimetres apart), and against itself (zero).
  r = run("distance " + path("quick.h5") + " " + path("quick.h5") + " --frame-b 0");
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string text = r.out;
  r = run("distance " + path("quick.h5") + " " + path("quick.h5") + " --frame-b 0 --json");
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json dj = nlohmann::json::parse(r.out);
  const double sym = dj["symmetric"]["mean_mm"].get<double>();
  EXPECT_GT(sym, 1.0);
  char printed[64];
  std::snprintf(printed, sizeof printed, "symmetric: %.2f +- %.2f mm", sym,
                dj["symmetric"]["sd_mm"].get<double>());
  EXPECT_NE(text.find(printed), std::string::npos) << text << " vs " << printed;
  EXPECT_EQ(dj["symmetric"]["n"].get<int>(),
            dj["a_to_b"]["n"].get<int>() + dj["b_to_a"]["n"].get<int>());
  r = run("distance " + path("quick.h5") + " " + path("quick.h5") + " --json");
  EXPECT_EQ(nlohmann::json::parse(r.out)["symmetric"]["max_mm"].get<double>(), 0.0);
  // Same seed, same result.
  ASSERT_EQ(run("phantom --seed 4 --out " + path("q.h5")).code, 0);
  const auto a = mvtwin::read_patient(path("p.h5")), b = mvtwin::read_patient(path("q.h5"));
  EXPECT_EQ(a.sequence.frames[0].la_surface->points(), b.sequence.frames[0].la_surface->points());
}

TEST_F(Cli, CalibrateSearchesOnTheSearchModelAndRecordsIt) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "a calibration's closures take too long under AddressSanitizer (2 min)";
#endif
  ASSERT_EQ(run("phantom --seed 4 --simulate-closure --quick --out " + path("obs.h5")).code, 0);
  const std::string base = "calibrate " + path("obs.h5") +
                           " --fit restlength_factor_anterolateral_marginal --no-scan "
                           "--max-sims 6 --set ures=16 --set vres=8 --out " +
                           path("c.h5");
  CmdResult r = run(base + " --search-set ures=12 --search-set vres=6");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("search on the 12 x 6 model"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("refine on the 16 x 8 model"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("searched on a cheaper model"), std::string::npos) << r.out;
  const mvtwin::CalibrationRecord c = mvtwin::read_calibration_file(path("c.h5"));
  EXPECT_GT(c.search_simulations, 0);
  EXPECT_GT(c.simulations, c.search_simulations);
  EXPECT_TRUE(std::isfinite(c.search_error_after_mm));
  EXPECT_NE(c.refinement.find("on the 16 x 8 model"), std::string::npos) << c.refinement;
  bool recorded = false;
  for (const auto& [k, v] : c.options) recorded |= k == "fit_search_model" && v == "ures=12,vres=6";
  EXPECT_TRUE(recorded) << "the search model is recorded by its differences";
  // A patient parameter is not a model option: refused by name, nothing replaced.
  r = run(base + " --force --search-set peak_pressure_mmhg=80");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--search-set"), std::string::npos) << r.err;
  EXPECT_EQ(mvtwin::read_calibration_file(path("c.h5")).search_simulations, c.search_simulations);
  // Contradicting options are a usage error; 16 x 8 has no default search model.
  EXPECT_EQ(run(base + " --force --no-search-model --search-set ures=12").code, 2);
  r = run(base + " --force");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(mvtwin::read_calibration_file(path("c.h5")).search_simulations, 0);
  EXPECT_EQ(r.out.find("searched on a cheaper model"), std::string::npos) << r.out;
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
  r = run("import --frame " + path("none.nii.gz") + " --out " + path("x.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("none.nii.gz: no such file"), std::string::npos) << r.err;
  r = run("frobnicate");
  EXPECT_NE(r.code, 0);
  EXPECT_FALSE(fs::exists(dir_ / "x.h5"));
}

TEST_F(Cli, TuneChordaeRefusesWhatIsNotANormalVirtualValve) {
  ASSERT_EQ(run("phantom --seed 2 --pathology functional_mr --out " + path("fmr.h5")).code, 0);
  CmdResult r = run("tune-chordae " + path("fmr.h5") + " --out " + path("t.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("functional_mr valve's leak is its pathology"), std::string::npos) << r.err;
  ASSERT_EQ(run("phantom --seed 2 --pathology normal --no-taut-chordae --out " + path("n.h5")).code,
            0);
  r = run("tune-chordae " + path("n.h5") + " --out " + path("t.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("no marginal chordae lengths"), std::string::npos) << r.err;
  // The generator's lengths (tune-chordae is what this test runs; phantom would tune them too).
  ASSERT_EQ(
      run("phantom --seed 2 --pathology normal --no-tune-normal-chordae --out " + path("n2.h5"))
          .code,
      0);
  r = run("tune-chordae " + path("n2.h5") + " --out " + path("t.h5") + " --set pressure=3");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("pressure"), std::string::npos) << r.err;
  r = run("tune-chordae " + path("n2.h5") + " --out " + path("t.h5") +
          " --set peak_pressure_mmhg=60");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("hidden parameters"), std::string::npos) << r.err;
  // Closing frames simulated with the old chordae would not be the tuned valve's.
  ASSERT_EQ(run("phantom --seed 2 --pathology normal --simulate-closure --quick "
                "--no-tune-normal-chordae --out " +
                path("obs.h5"))
                .code,
            0);
  r = run("tune-chordae " + path("obs.h5") + " --out " + path("t.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("closing frames were simulated"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("t.h5")));
  // A tuned valve tuned again records the second tuning once, in place of the first.
  const std::string quick = " --iterations 1 --set ures=16 --set vres=8";
  ASSERT_EQ(run("tune-chordae " + path("n2.h5") + " --out " + path("t.h5") + quick).code, 0);
  ASSERT_EQ(run("tune-chordae " + path("t.h5") + " --out " + path("t2.h5") + quick).code, 0);
  const Patient twice = mvtwin::read_patient(path("t2.h5"), false);
  int records = 0;
  for (const auto& [name, value] : twice.truth->anatomy)
    records += name == "chordae_tuning_eroa_mm2";
  EXPECT_EQ(records, 1);
  const std::string& source = twice.provenance.source;
  EXPECT_EQ(source.find("tuned to close"), source.rfind("tuned to close")) << source;
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
  // A result named .json would be replaced by its own summary: refused before any work.
  r = run("clip " + path("p.h5") + " --true-params --at 0.5 --out " + path("clip.json"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("the result is an HDF5 file"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("clip.json")));
  r = run("calibrate " + path("p.h5") + " --out " + path("c.json"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("the result is an HDF5 file"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("c.json")));
}

TEST_F(Cli, DetectionFromSyntheticTeeAndItsBenchmark) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP()
      << "simulating, rendering and training forests takes too long under AddressSanitizer";
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

  // A small virtual training cohort (coarse voxels and point spread, small forests), its truths
  // cached. The coarse PSF (the quick detection study's) renders ~4x faster: rendering samples
  // the beam at the PSF's scale whatever the voxel.
  const std::string small =
      " --voxel 2.5 --axial-psf 0.5 --lateral-psf 2.2 --trees 8 --samples 300 --jobs 2 --truth-set "
      "ures=16 --truth-set vres=8 "
      "--train-noise 0.004"
      " --cache " +
      path("cache");
  r = run("train-detector --virtual 3 --cohort-seed 77 --out " + path("m.yml.gz") + small);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("training on "), std::string::npos) << r.out;
  ASSERT_TRUE(fs::exists(dir_ / "m.yml.gz"));
  {
    std::ifstream f(path("m.yml.gz"));
    EXPECT_TRUE(f.good());
  }
  // The detection study of that model on one held-out patient (its truth cached beside the
  // others); its figures say what made them.
  const std::string study = "study detection --model " + path("m.yml.gz") +
                            " --test 1 --seed 77 --noise-levels 0.004,0.1 --out " + path("d") +
                            small;
  r = run(study);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  std::ifstream f(path("d/study.json"));
  std::stringstream js;
  js << f.rdbuf();
  const std::string j = js.str();
  for (const char* key :
       {"\"error_mean_mm\"", "\"error_sd_mm\"", "\"landmark_error_mm\"", "\"papillary_error_mm\"",
        "\"s_per_volume\"", "\"test_patients\"", "\"noise_levels\"",
        "\"posteromedial_papillary_tip\"", "\"synthetic\": true", "\"mvtwin_version\""})
    EXPECT_NE(j.find(key), std::string::npos) << key << " missing from\n" << j.substr(0, 2000);
  EXPECT_NE(r.out.find("paper (real TEE"), std::string::npos) << r.out;
  EXPECT_NE(r.err.find("[detect 2/2]"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::exists(dir_ / "d" / "report.html"));
  // Run again: everything is resumed, nothing is detected twice.
  r = run(study);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("done before (resumed)"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("s/volume"), std::string::npos) << r.err;
  // The benchmark it replaced is gone.
  r = run("bench detect --json " + path("b.json"));
  EXPECT_NE(r.code, 0);
}

TEST_F(Cli, CohortResumesAndSurvivesADamagedFile) {
  // Without tuning the normal valve (13 closures at 30 x 30: TuningTheNormalValvesOfACohort).
  const std::string cohort = "cohort --n 4 --seed 3 --no-tune-normal-chordae --out ";
  CmdResult r = run(cohort + path("c"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("made 4, kept 0, failed 0"), std::string::npos) << r.out;
  // Progress to a file (a log, CI) comes as one line per patient, not "\r"-joined.
  EXPECT_EQ(r.err.find('\r'), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("[cohort] 3/4 (made 3, kept 0, failed 0)\n"), std::string::npos) << r.err;
  const auto before = mvtwin::read_patient(path("c/patient_0002.h5"));
  fs::remove(dir_ / "c" / "patient_0001.h5");
  { std::ofstream(path("c/patient_0003.h5")) << "damaged"; }
  r = run(cohort + path("c"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("made 2, kept 2, failed 0"), std::string::npos) << r.out;
  EXPECT_NO_THROW(mvtwin::read_patient(path("c/patient_0003.h5")));
  const auto after = mvtwin::read_patient(path("c/patient_0002.h5"));
  EXPECT_EQ(before.provenance.created_utc, after.provenance.created_utc);  // kept, not remade
  EXPECT_TRUE(fs::exists(dir_ / "c" / "cohort.json"));
}

// The closing anatomy, the default: made unless refused, shown by info, a cohort made without it
// is remade with it (not reused), impossible clearances refused by name.
TEST_F(Cli, ClosingAnatomyOptionsAreRecordedAndACohortIsRemadeForThem) {
  CmdResult r = run("phantom --seed 4 --out " + path("p.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(mvtwin::read_patient(path("p.h5")).sequence.marginal_chordae_lengths.size(), 28u);
  r = run("info " + path("p.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("marginal lengths given at 28 sites"), std::string::npos) << r.out;
  r = run("phantom --seed 4 --no-taut-chordae --commissure-clearance 0 --out " + path("o.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(mvtwin::read_patient(path("o.h5")).sequence.marginal_chordae_lengths.empty());
  // (The normal valve's tuning, 13 closures at 30 x 30, is TuningTheNormalValvesOfACohort's.)
  const std::string untuned = " --no-tune-normal-chordae";
  r = run("cohort --n 2 --seed 3 --no-taut-chordae --out " + path("c") + untuned);
  ASSERT_EQ(r.code, 0) << r.err;
  r = run("cohort --n 2 --seed 3 --out " + path("c") + untuned);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("made 2, kept 0, failed 0"), std::string::npos) << r.out;
  r = run("cohort --n 2 --seed 3 --taut-chordae --out " + path("c") + untuned);
  EXPECT_NE(r.out.find("made 0, kept 2, failed 0"), std::string::npos) << r.out;
  EXPECT_FALSE(
      mvtwin::read_patient(path("c/patient_0001.h5")).sequence.marginal_chordae_lengths.empty());
  r = run("cohort --n 2 --seed 3 --commissure-clearance 0 --out " + path("c") + untuned);
  EXPECT_NE(r.out.find("made 2, kept 0, failed 0"), std::string::npos) << r.out;
  r = run("phantom --seed 4 --commissure-clearance -1 --out " + path("q.h5"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("--commissure-clearance"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "q.h5"));
}

// Edition 3's severity options: recorded in cohort.json and in each patient, a cohort made with
// edition 2's is remade (not reused) for today's, impossible scales refused by name.
TEST_F(Cli, SeverityOptionsAreRecordedAndACohortIsRemadeForThem) {
  const std::string cohort = "cohort --n 4 --seed 3 --no-tune-normal-chordae --out " + path("c");
  CmdResult r = run(cohort + " --no-myxomatous-flail --tethering-scale 1");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto flail2 = mvtwin::read_patient(path("c/patient_0002.h5"));
  const auto fmr2 = mvtwin::read_patient(path("c/patient_0003.h5"));
  r = run(cohort);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("made 4, kept 0, failed 0"), std::string::npos) << r.out;
  const auto flail3 = mvtwin::read_patient(path("c/patient_0002.h5"));
  const auto fmr3 = mvtwin::read_patient(path("c/patient_0003.h5"));
  EXPECT_NEAR(flail3.truth->parameters.pl_modulus_scale,
              0.6 * flail2.truth->parameters.pl_modulus_scale, 1e-12);
  auto depth = [](const mvtwin::Patient& p) {
    return p.truth->anatomy_or("papillary_depth_mm", std::nan(""));
  };
  EXPECT_GT(depth(fmr3), depth(fmr2) + 0.89);  // 0.3 x at least 3 mm deeper
  const nlohmann::json manifest = nlohmann::json::parse(std::ifstream(path("c/cohort.json")));
  EXPECT_EQ(manifest.at("myxomatous_flail"), true);
  EXPECT_EQ(manifest.at("tethering_scale"), 1.3);
  r = run(cohort + " --tethering-scale 1.3");
  EXPECT_NE(r.out.find("made 0, kept 4, failed 0"), std::string::npos) << r.out;
  r = run(cohort + " --tethering-scale 1");
  EXPECT_NE(r.out.find("made 4, kept 0, failed 0"), std::string::npos) << r.out;
  r = run("phantom --seed 4 --tethering-scale 4 --out " + path("q.h5"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("--tethering-scale"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "q.h5"));
}

/// The chordae tuning edition a patient records (0: none).
int tuning_edition(const mvtwin::Patient& p) {
  for (const auto& [name, value] : p.truth->anatomy)
    if (name == "chordae_tuning_edition") return static_cast<int>(value);
  return 0;
}

TEST_F(Cli, TuningTheNormalValvesOfACohort) {
  // On the cohort's own grid (coarse here: a few seconds): patient 0 is normal, 1 is not.
  const std::string coarse = "cohort --n 2 --seed 2026 --ures 16 --vres 8 --out ";
  CmdResult r = run(coarse + path("plain") + " --no-tune-normal-chordae");
  ASSERT_EQ(r.code, 0) << r.err;
  r = run(coarse + path("tuned"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("virtual-2026-0 (normal): chordae tuned, EROA"), std::string::npos) << r.out;
  const mvtwin::Patient plain = mvtwin::read_patient(path("plain/patient_0000.h5"));
  const mvtwin::Patient tuned = mvtwin::read_patient(path("tuned/patient_0000.h5"));
  EXPECT_EQ(tuning_edition(plain), 0);
  EXPECT_GE(tuning_edition(tuned), 2);
  ASSERT_EQ(plain.sequence.marginal_chordae_lengths.size(),
            tuned.sequence.marginal_chordae_lengths.size());
  double moved = 0;
  for (size_t j = 0; j < plain.sequence.marginal_chordae_lengths.size(); ++j)
    moved += std::abs(plain.sequence.marginal_chordae_lengths[j].length_mm -
                      tuned.sequence.marginal_chordae_lengths[j].length_mm);
  EXPECT_GT(moved, 0.5);
  // The sick valve is the generator's, to the bit.
  const mvtwin::Patient sick_plain = mvtwin::read_patient(path("plain/patient_0001.h5"));
  const mvtwin::Patient sick_tuned = mvtwin::read_patient(path("tuned/patient_0001.h5"));
  for (size_t j = 0; j < sick_plain.sequence.marginal_chordae_lengths.size(); ++j)
    EXPECT_EQ(sick_plain.sequence.marginal_chordae_lengths[j].length_mm,
              sick_tuned.sequence.marginal_chordae_lengths[j].length_mm);
  // The manifest says so; a rerun keeps both, and one without tuning remakes the normal valve.
  std::ifstream mf(path("tuned/cohort.json"));
  const nlohmann::json m = nlohmann::json::parse(mf);
  EXPECT_EQ(m["tune_normal_chordae"], true);
  EXPECT_EQ(m["chordae_tuning_edition"], tuning_edition(tuned));
  EXPECT_TRUE(m["patients"][0].contains("chordae_tuning"));
  EXPECT_FALSE(m["patients"][1].contains("chordae_tuning"));
  EXPECT_LT(m["patients"][0]["chordae_tuning"]["eroa_mm2"].get<double>(),
            m["patients"][0]["chordae_tuning"]["eroa_before_mm2"].get<double>());
  r = run(coarse + path("tuned"));
  EXPECT_NE(r.out.find("made 0, kept 2, failed 0"), std::string::npos) << r.out;
  r = run(coarse + path("tuned") + " --no-tune-normal-chordae");
  EXPECT_NE(r.out.find("made 1, kept 1, failed 0"), std::string::npos) << r.out;
  EXPECT_EQ(tuning_edition(mvtwin::read_patient(path("tuned/patient_0000.h5"))), 0);
  // A normal phantom too (--quick: tuned on the quick closure's 20 x 10), unless told not to.
  // Not under ASan: the same tuning as the cohort's above, on a finer grid (the ASan run's
  // longest test took 122 s with it).
#ifdef __SANITIZE_ADDRESS__
  return;
#endif
  r = run("phantom --seed 2 --pathology normal --quick --out " + path("q.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("(normal): chordae tuned, EROA"), std::string::npos) << r.out;
  EXPECT_GE(tuning_edition(mvtwin::read_patient(path("q.h5"))), 2);
  r = run("phantom --seed 2 --pathology normal --quick --no-tune-normal-chordae --out " +
          path("u.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(tuning_edition(mvtwin::read_patient(path("u.h5"))), 0);
}

TEST_F(Cli, ImportRealSegmentation) {
  const fs::path seg = fs::path(MVTWIN_SHARED_DATA_DIR) / "mvtool-008" / "008_gt.nii.gz";
  if (!fs::exists(seg))
    GTEST_SKIP() << "../shared/data absent (a user's clone has no ../shared): skipped";
  CmdResult r = run("import --frame " + seg.string() + " --out " + path("008.h5") + " --json " +
                    path("008.json"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("surface -> mask"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("the leaflet rim is"), std::string::npos) << r.out;  // both annuli reported
  EXPECT_TRUE(fs::exists(path("008.json")));
  r = run("info " + path("008.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out.find("SYNTHETIC"), std::string::npos);  // real data is never labelled synthetic
  EXPECT_NE(r.out.find("ASSUMED"), std::string::npos) << r.out;  // the papillary tips
  EXPECT_NE(r.out.find("import    frame 0"), std::string::npos)
      << r.out;  // the fit, as import printed it
  EXPECT_NE(r.out.find("surface -> mask"), std::string::npos) << r.out;
  const fs::path pred = seg.parent_path() / "008_pred.nii.gz";
  ASSERT_EQ(run("import --frame " + pred.string() + " --out " + path("pred.h5")).code, 0);
  ASSERT_EQ(
      run("import --frame " + seg.string() + " --no-annulus-label --out " + path("rim.h5")).code,
      0);
  r = run("distance " + path("008.h5") + " " + path("pred.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("symmetric: "), std::string::npos);
  // A surface against itself is at distance zero.
  r = run("distance " + path("008.h5") + " " + path("008.h5"));
  EXPECT_NE(r.out.find("symmetric: 0.00 +- 0.00 mm"), std::string::npos) << r.out;
  r = run("import --frame " + seg.string() + " --labels 2,9,1 --out " + path("bad.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("label 9 (posterior leaflet) has 0 voxels"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("bad.h5")));
  // One closed frame: simulate refuses it clearly.
  r = run("simulate " + path("008.h5") + " --out " + path("sim.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("end-diastolic frame"), std::string::npos) << r.err;
}

// The real-patient path on label maps and markups written from a virtual patient: export,
// import (open and closed frames, tips from markups), simulate.
TEST_F(Cli, ImportLabelMapsOfAVirtualPatientAndSimulate) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "a closure simulation takes too long under AddressSanitizer";
#endif
  CmdResult r = run(
      "phantom --seed 4 --simulate-closure --noise 0 --closure-set ures=16 --closure-set vres=10 "
      "--closure-set dt=0.01 --closure-set layers=1 --out " +
      path("v.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  const Patient v = mvtwin::read_patient(path("v.h5"));
  const int ed = v.sequence.end_diastole, fc = v.sequence.first_closed;
  r = run("export " + path("v.h5") + " --labelmap " + path("seg") +
          " --convention mvseg --voxel 0.8 --frames " + std::to_string(ed) + "," +
          std::to_string(fc));
  ASSERT_EQ(r.code, 0) << r.err;
  char name[64];
  std::snprintf(name, sizeof name, "seg/frame_%02d.nii.gz", ed);
  const std::string f_ed = path(name);
  std::snprintf(name, sizeof name, "seg/frame_%02d.nii.gz", fc);
  const std::string f_fc = path(name);
  std::snprintf(name, sizeof name, "seg/tips_%02d.mrk.json", ed);
  const std::string m_ed = path(name);
  char t_ed[32], t_fc[32];
  std::snprintf(t_ed, sizeof t_ed, "%.4f", v.sequence.frames[ed].time_s);
  std::snprintf(t_fc, sizeof t_fc, "%.4f", v.sequence.frames[fc].time_s);
  // Duplicate frame times are refused, and nothing is written.
  r = run("import --convention mvseg --frame " + f_ed + "@0.1 --frame " + f_fc + "@0.1 --out " +
          path("dup.h5"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("have the same time"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("dup.h5")));
  r = run("import --convention mvseg --frame " + f_fc + "@" + t_fc + " --frame " + f_ed + "@" +
          t_ed + " --markups " + m_ed + "@" + t_ed + " --out " + path("imp.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("[end-diastole]"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("[first closed]"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("annulus: leaflet rim"), std::string::npos) << r.out;
  const Patient imp = mvtwin::read_patient(path("imp.h5"));
  EXPECT_FALSE(imp.synthetic);
  ASSERT_EQ(imp.sequence.num_frames(), 2);
  EXPECT_EQ(imp.sequence.end_diastole, 0);
  EXPECT_EQ(imp.sequence.first_closed, 1);
  // The tips came from the markups (held in the closed frame, which had none: noted as assumed).
  EXPECT_FALSE(imp.sequence.frames[0].assumed(Landmark::kAnterolateralPapillaryTip));
  EXPECT_LT((imp.sequence.frames[0].landmark(Landmark::kAnterolateralPapillaryTip) -
             v.sequence.frames[ed].landmark(Landmark::kAnterolateralPapillaryTip))
                .norm(),
            1e-3);
  EXPECT_TRUE(imp.sequence.frames[1].assumed(Landmark::kAnterolateralPapillaryTip));
  // Each imported surface lies on the virtual one.
  for (int k = 0; k < 2; ++k) {
    const SymmetricDistance d =
        symmetric_surface_distance(imp.sequence.frames[k].la_surface->triangulate(),
                                   v.sequence.frames[k ? fc : ed].la_surface->triangulate());
    EXPECT_LT(d.symmetric.mean, 0.5) << "frame " << k;
  }
  // The end-diastolic map as 3D Slicer writes a segmentation: .seg.nrrd, LPS, unsigned char,
  // segments found by their names (no --labels): it lands where the NIfTI (RAS) one does.
  {
    const ImageVolume im = mvtwin::read_nifti(f_ed);
    std::ofstream o(path("ed.seg.nrrd"), std::ios::binary);
    auto vec = [](const Eigen::Vector3d& x) {
      char b[128];
      std::snprintf(b, sizeof b, "(%.17g,%.17g,%.17g)", x.x(), x.y(), x.z());
      return std::string(b);
    };
    const Eigen::Vector3d flip(-1, -1, 1);
    o << "NRRD0004\n# Complete NRRD file format specification at:\n# "
         "http://teem.sourceforge.net/nrrd/format.html\n"
      << "type: unsigned char\ndimension: 3\nspace: left-posterior-superior\nsizes: " << im.size[0]
      << " " << im.size[1] << " " << im.size[2] << "\nspace directions:";
    for (int k = 0; k < 3; ++k)
      o << " " << vec(flip.cwiseProduct(im.direction.col(k) * im.spacing[k]));
    o << "\nkinds: domain domain domain\nencoding: raw\nspace origin: "
      << vec(flip.cwiseProduct(im.origin)) << "\n"
      << "Segment0_Color:=0.5 0.7 "
         "0.3\nSegment0_ID:=Segment_1\nSegment0_LabelValue:=1\nSegment0_Layer:=0\n"
      << "Segment0_Name:=Posterior "
         "leaflet\nSegment1_ID:=Segment_2\nSegment1_LabelValue:=2\nSegment1_Layer:=0\n"
      << "Segment1_Name:=Anterior leaflet\nSegmentation_MasterRepresentation:=Binary labelmap\n\n";
    for (float label : im.data)
      o.put(static_cast<char>(static_cast<unsigned char>(std::lround(label))));
  }
  r = run("import --frame " + path("ed.seg.nrrd") + "@" + t_ed + " --frame " + f_fc + "@" + t_fc +
          " --convention mvseg --markups " + m_ed + "@" + t_ed + " --out " + path("seg.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  const Patient seg = mvtwin::read_patient(path("seg.h5"));
  EXPECT_LT(
      (seg.sequence.frames[0].la_surface->points() - imp.sequence.frames[0].la_surface->points())
          .cwiseAbs()
          .maxCoeff(),
      1e-6);
  // The same frames as leaflet surface meshes: two files at end-diastole (STL and PLY, in LPS as
  // 3D Slicer writes them, with its SPACE mark), one file holding both leaflets when closed.
  for (int k = 0; k < 2; ++k) {
    auto [anterior_mesh, posterior_mesh] = mvtwin::detection::leaflet_surface_meshes(
        *v.sequence.frames[k ? fc : ed].la_surface, 48, 30);
    mvtwin::TriangleMesh leaf[2] = {anterior_mesh, posterior_mesh};
    for (int l = 0; l < 2 && k == 0; ++l) leaf[l].V.leftCols(2) *= -1.0;  // LPS
    if (k == 0) {
      mvtwin::write_surface_mesh(path("ed_al.stl"), leaf[0], "LPS");
      mvtwin::write_surface_mesh(path("ed_pl.ply"), leaf[1], "LPS");
    } else {
      mvtwin::TriangleMesh both;
      both.V.resize(leaf[0].V.rows() + leaf[1].V.rows(), 3);
      both.V << leaf[0].V, leaf[1].V;
      both.F.resize(leaf[0].F.rows() + leaf[1].F.rows(), 3);
      both.F << leaf[0].F, (leaf[1].F.array() + static_cast<int>(leaf[0].V.rows())).matrix();
      mvtwin::write_surface_mesh(path("fc.vtp"), both, "RAS");
    }
  }
  r = run("import --mesh " + path("ed_al.stl") + "," + path("ed_pl.ply") + "@" + t_ed + " --mesh " +
          path("fc.vtp") + "@" + t_fc + " --markups " + m_ed + "@" + t_ed + " --out " +
          path("mesh.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  const Patient mesh = mvtwin::read_patient(path("mesh.h5"));
  for (int k = 0; k < 2; ++k) {
    const SymmetricDistance d =
        symmetric_surface_distance(mesh.sequence.frames[k].la_surface->triangulate(),
                                   v.sequence.frames[k ? fc : ed].la_surface->triangulate());
    EXPECT_LT(d.symmetric.mean, 0.5) << "mesh frame " << k;
  }
  // Both frames as one 3D+t label map (3D Slicer's .seq.nrrd, times in the file).
  r = run("export " + path("v.h5") + " --labelmap " + path("seq") +
          " --sequence --convention mvtool --frames " + std::to_string(ed) + "," +
          std::to_string(fc));
  ASSERT_EQ(r.code, 0) << r.err;
  ASSERT_TRUE(fs::exists(path("seq/labels.seq.nrrd")));
  r = run("import --sequence " + path("seq/labels.seq.nrrd") + " --markups " + m_ed + "@" + t_ed +
          " --out " + path("seq.h5"));
  ASSERT_EQ(r.code, 0) << r.err;
  const Patient sq = mvtwin::read_patient(path("seq.h5"));
  ASSERT_EQ(sq.sequence.num_frames(), 2);
  EXPECT_NEAR(sq.sequence.frames[1].time_s, v.sequence.frames[fc].time_s, 1e-4);
  for (int k = 0; k < 2; ++k) {
    const SymmetricDistance d =
        symmetric_surface_distance(sq.sequence.frames[k].la_surface->triangulate(),
                                   v.sequence.frames[k ? fc : ed].la_surface->triangulate());
    EXPECT_LT(d.symmetric.mean, 0.5) << "sequence frame " << k;
  }
  // The benchmark's figures and fields (one patient, one voxel size: the command, not the numbers).
  r = run(
      "bench import --patients 1 --voxels 0.8 --closure-set ures=16 --closure-set vres=10 --json " +
      path("bench.json"));
  ASSERT_EQ(r.code, 0) << r.err;
  {
    std::ifstream in(path("bench.json"));
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (const char* key :
         {"\"rows\"", "\"voxel_mm\"", "\"convention\"", "\"surface_error_open_mm\"",
          "\"surface_error_closed_mm\"", "\"annulus_error_mm\"", "\"s_per_frame\"", "\"mvseg\"",
          "\"mvtool\"", "SYNTHETIC"})
      EXPECT_NE(text.find(key), std::string::npos) << key;
  }
  r = run("bench import --patients 1 --closure-set peak_pressure_mmhg=80");
  EXPECT_EQ(r.code, 1);  // a parameter is refused, not silently dropped
  EXPECT_NE(r.err.find("a patient parameter"), std::string::npos) << r.err;
  r = run("simulate " + path("imp.h5") + " --out " + path("imp_sim.h5") +
          " --set ures=16 --set vres=10");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("ASSUMED"), std::string::npos) << r.out;
  r = run("info " + path("imp_sim.h5"));  // the result file records what its input assumed
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("input ASSUMED (estimated from published anatomy, not observed): "
                       "anterolateral_papillary_tip"),
            std::string::npos)
      << r.out;
}

}  // namespace

// bench closure's at-rest comparison: with the reference made with the timed run's own settings
// (both unsettled: settle_mm=0, the paper's end state) the error against it is exactly zero,
// while the same settings held at peak pressure until at rest (settling) end elsewhere: the lag
// is positive and reported with its settling; --no-rest leaves it out. Settled to 0.01 mm, the
// timed run lags behind rest less than half as much. --ref-set adds to the reference's defaults:
// the reference keeps their fixed steps (the timed run asks for them) and takes the timed run's
// grid, dt and tolerance; were the defaults replaced, the reference would take error-controlled
// steps and the error not be 0. The paired run (static_rest=on by default) is the same closure
// brought to rest by the static solve: its residual history is recorded, it ends nearer the
// grid's own rest than the unsettled run, and two patients give a row each per variant.
TEST_F(Cli, BenchClosureMeasuresTheLagBehindRest) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "several closures: too long under AddressSanitizer";
#endif
  const std::string small =
      " --set ures=12 --set vres=6 --set step_error_mm=0 --ref-set ures=12 --ref-set vres=6 "
      "--ref-set dt=0.01 --ref-set pcg_tolerance=0.1 --repeat 1 --json ";
  CmdResult r =
      run("bench closure --set settle_mm=0 --ref-set settle_mm=0" + small + path("rest.json"));
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  auto read = [](const std::string& file) { return nlohmann::json::parse(std::ifstream(file)); };
  const nlohmann::json j = read(path("rest.json"));
  ASSERT_EQ(j["runs"].size(), 2u) << j.dump(1).substr(0, 3000);
  const nlohmann::json& timed = j["runs"][0];
  const nlohmann::json& paired = j["runs"][1];
  EXPECT_EQ(timed["variant"], "timed");
  EXPECT_EQ(timed["error_mean_mm"].get<double>(), 0.0) << "the reference has its settings";
  EXPECT_GT(timed["rest_lag_mean_mm"].get<double>(), 0.0);
  EXPECT_GE(timed["rest_lag_max_mm"].get<double>(), timed["rest_lag_mean_mm"].get<double>());
  EXPECT_GT(timed["rest_settle_steps"].get<double>(), 0.0);
  EXPECT_NE(r.out.find("lag behind own rest"), std::string::npos) << r.out;
  EXPECT_EQ(paired["variant"], "paired");
  EXPECT_EQ(paired["added_settings"], nlohmann::json::array({"static_rest=on"}));
  ASSERT_TRUE(paired.contains("static_history_n")) << paired.dump(1);
  EXPECT_GT(paired["static_iterations"].get<int>(), 0);
  EXPECT_EQ(paired["static_history_n"].size(), paired["static_iterations"].get<size_t>() + 1);
  EXPECT_LT(paired["rest_lag_mean_mm"].get<double>(), timed["rest_lag_mean_mm"].get<double>());
  EXPECT_GT(paired["error_mean_mm"].get<double>(), 0.0);
  r = run("bench closure --no-rest --no-pair --seeds 1,2" + small + path("norest.json"));
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json norest = read(path("norest.json"));
  ASSERT_EQ(norest["runs"].size(), 2u);
  EXPECT_EQ(norest["runs"][1]["patient_seed"], 2);
  EXPECT_FALSE(norest["runs"][0].contains("rest_lag_mean_mm"));
  r = run("bench closure --no-pair --set settle_mm=0.01" + small + path("settled.json"));
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_LT(read(path("settled.json"))["runs"][0]["rest_lag_mean_mm"].get<double>(),
            0.5 * timed["rest_lag_mean_mm"].get<double>());
  // Two references need a file each.
  r = run("bench closure --seeds 1,2 --ref-file " + path("ref.h5") + small + path("x.json"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("{seed}"), std::string::npos) << r.err;
  r = run("bench closure --no-pair --pair-set static_rest=on" + small + path("x.json"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("contradict"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("x.json")));
}

TEST_F(Cli, StudyCommandsRefuseWhatTheyCannotUse) {
  // A patient parameter given as a model option is refused, not dropped.
  CmdResult r = run("study cohort --quick --patients 1 --observe-set peak_pressure_mmhg=80 --out " +
                    path("c"));
  EXPECT_EQ(r.code, 1) << r.out << r.err;
  EXPECT_NE(r.err.find("patient parameter"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("c") + "/study.json"));
  r = run("study sensitivity --quick --set restlength_factor_anterolateral_marginal=1.1 --out " +
          path("s"));
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("patient parameter"), std::string::npos) << r.err;
  r = run("study cohort --quick --set no_such_option=1 --out " + path("c"));
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("no_such_option"), std::string::npos) << r.err;
  r = run("study cohort --quick --method newton --out " + path("c"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("newton"), std::string::npos) << r.err;
  r = run("study nonsense --out " + path("c"));
  EXPECT_NE(r.code, 0);
  r = run("study convergence --quick --set peak_pressure_mmhg=80 --out " + path("v"));
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("patient parameter"), std::string::npos) << r.err;
  r = run("study convergence --quick --dt 0.01,0.02 --out " + path("v"));
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("dt must decrease"), std::string::npos) << r.err;
  r = run("study clip --quick --positions 0.5,1.5 --out " + path("k"));
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("positions"), std::string::npos) << r.err;
  r = run("study clip --quick --fit restlength,leaflet_colour --out " + path("k"));
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("leaflet_colour"), std::string::npos) << r.err;
  r = run("study clip --quick --fit \"\" --out " + path("k"));  // not the default in disguise
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("nothing chosen to fit"), std::string::npos) << r.err;
  r = run("study robustness --quick --set marginal_stiffness_scale=2 --out " + path("r"));
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("patient parameter"), std::string::npos) << r.err;
  for (const char* d : {"v", "k", "r"}) EXPECT_FALSE(fs::exists(path(d) + "/study.json")) << d;
  // Nor do the benchmarks and the phantom's closure model drop a parameter.
  r = run("bench closure --set peak_pressure_mmhg=80 --json " + path("b.json"));
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("patient parameter"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("b.json")));
  r = run("phantom --seed 2 --simulate-closure --closure-set al_modulus_scale=2 --out " +
          path("ph.h5"));
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("patient parameter"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("ph.h5")));
  // The benchmarks that became studies are gone, not silently kept.
  for (const char* b : {"bench accuracy", "bench stability", "bench calibrate"}) {
    r = run(std::string(b) + " --json " + path("b.json"));
    EXPECT_NE(r.code, 0) << b;
    EXPECT_FALSE(fs::exists(path("b.json"))) << b;
  }
}

TEST_F(Cli, QuickConvergenceAndRobustnessStudiesPrintTheirTables) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "the studies themselves run under AddressSanitizer in tests/studies; what this "
                  "adds (the printed table) the test flavour checks (59 s under ASan)";
#endif
  CmdResult r = run("study convergence --quick --out " + path("v"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("(reference)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("[SYNTHETIC]"), std::string::npos) << r.out;
  EXPECT_NE(r.err.find("[simulate 12/12]"), std::string::npos) << r.err;  // 6 models, paired
  EXPECT_NE(r.out.find("paired: wall_s"), std::string::npos) << r.out;
  // (study clip --quick runs as the --help examples test runs it)
  r = run("study robustness --quick --runs 3 --out " + path("r"));
  ASSERT_TRUE(r.code == 0 || r.code == 5) << r.err;
  EXPECT_NE(r.out.find("3 cases:"), std::string::npos) << r.out;
  for (const char* d : {"v", "r"}) EXPECT_TRUE(fs::exists(path(d) + "/report.html")) << d;
}

TEST_F(Cli, QuickCohortStudyPrintsItsTableNextToThePaper) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "the cohort study runs under AddressSanitizer in tests/studies; what this adds "
                  "(the printed table) the test flavour checks (50 s under ASan)";
#endif
  const CmdResult r = run("study cohort --quick --patients 2 --out " + path("c"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("paper (25 patients)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("SYNTHETIC"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(path("c") + "/report.html"));
}
