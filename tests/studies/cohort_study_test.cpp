// The cohort study: what it writes, that it resumes without redoing, that a bad patient does
// not stop it, and that MPI ranks give the single process's numbers.
#include "mvtwin/studies/cohort_study.h"

#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include <gtest/gtest.h>

#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/table_file.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/forward/chordae_tuning.h"
#include "mvtwin/studies/scaling.h"
#include "mvtwin/studies/work_pool.h"

#include "../support/small_models.h"

namespace fs = std::filesystem;
using nlohmann::json;
using namespace mvtwin;
using namespace mvtwin::studies;

namespace {

class CohortStudy : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("mvtwin_study_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  CohortStudyOptions quick(int n) const {
    CohortStudyOptions o = CohortStudyOptions::quick();
    o.patients = n;
    o.out = dir_ / "study";
    if (test_support::small_models()) {  // coarser observations and models
      o.observation.simulation.model.ures = 14;
      o.observation.simulation.model.vres = 8;
      o.model.model.ures = 12;
      o.model.model.vres = 6;
      o.fit_model = o.model;
    }
    return o;
  }
  static json read_json(const fs::path& p) {
    std::ifstream f(p);
    return json::parse(f);
  }
  fs::path dir_;
};

/// The numbers of a study (not its times or where it ran).
json numbers_of(const json& study) {
  json out = json::array();
  for (const auto& p : study["patients"])
    out.push_back({p["id"], p["pathology"], p["status"], p["error_default_mm"],
                   p["error_default_p95_mm"], p["orifice_mm2"], p["coaptation_mm"], p["rating"],
                   p["error_calibrated_mm"]});
  return out;
}

TEST(ClosureRating, TheObservedOrificeCapturedOrNot) {
  const ClosureRating r;  // within max(3 mm^2, 25 %) of the observed EROA
  EXPECT_EQ(r.rate(0.0, 0.0), "satisfactory");
  EXPECT_EQ(r.rate(3.0, 0.0), "satisfactory");
  EXPECT_EQ(r.rate(50.0, 40.0), "satisfactory");   // 25 % of 40 is 10
  EXPECT_EQ(r.rate(5.5, 0.0), "passable");         // within twice the tolerance
  EXPECT_EQ(r.rate(60.0, 42.0), "passable");       // both severe
  EXPECT_EQ(r.rate(0.0, 45.0), "unsatisfactory");  // closed where the valve leaks
  EXPECT_EQ(r.rate(30.0, 0.5), "unsatisfactory");
  EXPECT_EQ(r.rate(std::nan(""), 0.0), "unsatisfactory");
  // Without an observed orifice, by the grade alone.
  EXPECT_EQ(r.rate(0.5, std::nan("")), "satisfactory");
  EXPECT_EQ(r.rate(10.0, std::nan("")), "passable");
  EXPECT_EQ(r.rate(25.0, std::nan("")), "unsatisfactory");
  ClosureRating bad;
  bad.match_mm2 = -1.0;
  std::string e;
  EXPECT_FALSE(bad.is_valid(&e));
  EXPECT_NE(e.find("EROA"), std::string::npos);
}

TEST_F(CohortStudy, QuickStudyWritesEveryPatientWithItsErrorAndRating) {
  CohortStudyOptions o = quick(3);
  int events = 0;
  o.progress = [&](const StudyEvent&) { ++events; };
  auto pool = make_local_pool();
  const CohortStudyResult r = run_cohort_study(o, *pool);
  EXPECT_GT(events, 0);
  const json j = read_json(o.out / "study.json");
  ASSERT_EQ(j["patients"].size(), 3u);
  EXPECT_TRUE(j["synthetic"].get<bool>());
  EXPECT_EQ(j["provenance"]["seed"].get<std::uint64_t>(), o.seed);
  std::set<std::string> pathologies;
  for (const auto& p : j["patients"]) {
    for (const char* k :
         {"id", "pathology", "status", "error_default_mm", "error_calibrated_mm", "rating"})
      EXPECT_TRUE(p.contains(k)) << k;
    EXPECT_EQ(p["status"], "ok") << p.dump();
    const double e = p["error_default_mm"].get<double>();
    // The observation's noise is 0.5 mm: a simulation cannot match it much better than that on
    // average, and a default closure of a virtual valve is not centimetres away.
    EXPECT_GT(e, 0.2);
    EXPECT_LT(e, 5.0);
    EXPECT_GE(p["error_default_p95_mm"].get<double>(), e);
    EXPECT_TRUE(p["error_calibrated_mm"].is_null());  // not calibrated in the quick size
    EXPECT_TRUE(p["rating"] == "satisfactory" || p["rating"] == "passable" ||
                p["rating"] == "unsatisfactory");
    pathologies.insert(p["pathology"].get<std::string>());
    EXPECT_EQ(p["observed_with"], "as given") << p.dump();  // no observation needed a retry
  }
  EXPECT_EQ(pathologies.size(), 3u);  // the pathologies in turn
  EXPECT_EQ(j["summary"]["observations"]["as_given"].get<int>(), 3);
  EXPECT_EQ(j["summary"]["observations"]["lost"].get<int>(), 0);
  EXPECT_TRUE(j["summary"]["observations"]["retried"].empty());
  // The HDF5 table holds the same numbers.
  const TableFile t = read_table_file(o.out / "study.h5");
  EXPECT_EQ(t.format, "mvtwin-cohort-study");
  const TableColumn* err = nullptr;
  for (const auto& c : t.columns)
    if (c.name == "error_default_mm") err = &c;
  ASSERT_NE(err, nullptr);
  ASSERT_EQ(err->numbers.size(), 3u);
  for (int i = 0; i < 3; ++i)
    EXPECT_DOUBLE_EQ(err->numbers[static_cast<std::size_t>(i)],
                     j["patients"][i]["error_default_mm"].get<double>());
  EXPECT_EQ(err->units, "mm");
  // The report cites the paper and shows its plots.
  std::ifstream md(o.out / "report.md");
  std::stringstream s;
  s << md.rdbuf();
  EXPECT_NE(s.str().find("Mansi"), std::string::npos);
  EXPECT_NE(s.str().find("1.49 ± 0.62"), std::string::npos);
  EXPECT_NE(s.str().find("Observed closures: 3 by the observation model as given, 0 by a safer "
                         "retry"),
            std::string::npos);
  for (const char* png : {"errors_per_patient.png", "errors_by_pathology.png", "ratings.png"}) {
    EXPECT_GT(fs::file_size(o.out / png), 1000u) << png;
    EXPECT_NE(s.str().find(png), std::string::npos) << png;
  }
  EXPECT_GT(fs::file_size(o.out / "report.html"),
            fs::file_size(o.out / "ratings.png"));  // embedded
  EXPECT_EQ(r.patients.size(), 3u);
}

// Patients two at a time (each with its calibration's candidates in parallel too) against one
// at a time: the same numbers bit for bit (scripts/tsan runs this under ThreadSanitizer).
TEST_F(CohortStudy, ConcurrentPatientsGiveTheSequentialNumbers) {
#ifdef __SANITIZE_ADDRESS__
  // Three observed closures twice (4.5 min under AddressSanitizer); the same code runs in
  // QuickStudyWritesEveryPatientWithItsErrorAndRating, its threads under ThreadSanitizer
  // (scripts/tsan).
  GTEST_SKIP() << "six closures take too long under AddressSanitizer (scripts/tsan runs this)";
#endif
  CohortStudyOptions two = quick(3);
  two.jobs = 2;
  CohortStudyOptions one = two;
  one.jobs = 1;
  one.out = dir_ / "one";
  auto pool = make_local_pool();
  run_cohort_study(two, *pool);
  run_cohort_study(one, *pool);
  const json a = numbers_of(read_json(two.out / "study.json")),
             b = numbers_of(read_json(one.out / "study.json"));
  ASSERT_EQ(a.size(), 3u);
  EXPECT_EQ(a, b);
}

TEST_F(CohortStudy, ResumedStudyRedoesNothingAndGivesTheSameNumbers) {
  CohortStudyOptions o = quick(2);
  auto pool = make_local_pool();
  run_cohort_study(o, *pool);
  const json first = read_json(o.out / "study.json");
  // A killed run: one patient's record lost, the study file gone.
  fs::remove(o.out / "records" / "patient_0001.json");
  fs::remove(o.out / "study.json");
  std::vector<std::string> simulated, resumed;
  o.progress = [&](const StudyEvent& e) {
    if (e.message.find("simulating") != std::string::npos) simulated.push_back(e.message);
    if (e.message.find("resumed") != std::string::npos) resumed.push_back(e.message);
  };
  run_cohort_study(o, *pool);
  EXPECT_TRUE(simulated.empty()) << "observations are cached";
  ASSERT_EQ(resumed.size(), 1u);
  EXPECT_NE(resumed[0].find("patient_0000"), std::string::npos);
  EXPECT_EQ(numbers_of(read_json(o.out / "study.json")), numbers_of(first));
}

TEST_F(CohortStudy, CalibrationSearchesOnTheFitModelAndReportsOnTheStudyModel) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "a calibration's closures take too long under AddressSanitizer (6 min)";
#endif
  CohortStudyOptions o = quick(1);
  o.calibrate = true;
  o.fit = "pressure";  // one parameter: a short search
  o.max_simulations = 8;
  o.fit_model.model.ures = 12;  // another grid than the reporting model's (16 x 12; small: 12 x 6)
  o.fit_model.model.vres = 8;
  auto pool = make_local_pool();
  const CohortStudyResult r = run_cohort_study(o, *pool);
  ASSERT_EQ(r.patients.size(), 1u);
  const CohortPatient& p = r.patients[0];
  ASSERT_EQ(p.status, "ok") << p.reason;
  ASSERT_TRUE(std::isfinite(p.error_calibrated_mm)) << p.reason;
  // The search's 8, then the refinement on the reporting model: the start, the search's fit,
  // one Jacobian point and at most two Gauss-Newton steps.
  EXPECT_GE(p.simulations, 1 + 3);
  EXPECT_LE(p.simulations, 8 + 5);
  // The search keeps its best point, which is at least as good as its start (the defaults).
  EXPECT_LE(p.error_calibrated_fit_model_mm, p.error_default_fit_model_mm + 1e-12);
  // Two models: the search's figures are not the reported ones, and the fit was refined on
  // the reporting model.
  EXPECT_NE(p.error_default_fit_model_mm, p.error_default_mm);
  EXPECT_NE(p.error_calibrated_fit_model_mm, p.error_calibrated_mm);
  const std::string reporting = "on the " + std::to_string(o.model.model.ures) + " x " +
                                std::to_string(o.model.model.vres) + " model";
  EXPECT_NE(p.refinement.find(reporting), std::string::npos) << p.refinement;
  // What bench calibrate reported: the fit's SD and identifiability per parameter, its cost.
  ASSERT_TRUE(p.fitted.contains("peak_pressure")) << p.fitted.dump();
  EXPECT_TRUE(p.identified.contains("peak_pressure")) << p.identified.dump();
  EXPECT_TRUE(p.sd.contains("peak_pressure")) << p.sd.dump();
  EXPECT_FALSE(p.termination.empty());
  EXPECT_GE(p.failed_simulations, 0);
  EXPECT_LE(p.failed_simulations, p.simulations);
  const json j = read_json(o.out / "study.json");
  EXPECT_TRUE(j["patients"][0]["error_calibrated_fit_model_mm"].is_number());
  EXPECT_EQ(j["patients"][0]["refinement"], p.refinement);
  EXPECT_EQ(j["patients"][0]["identified"], p.identified);
  EXPECT_EQ(j["config"]["fit_model"]["ures"], "12");
  const json& cal = j["summary"]["calibration"];
  EXPECT_EQ(cal["calibrated"], 1);
  EXPECT_EQ(cal["simulations"]["mean"].get<double>(), p.simulations);
  EXPECT_EQ(cal["restlength_recovery"]["identified"], 0);  // no rest length fitted
  EXPECT_EQ(cal["restlength_recovery"]["unidentified"], 0);
  // The ratio to the observation noise is the mean error after over the noise SD.
  EXPECT_NEAR(cal["error_calibrated_over_noise"]["mean"].get<double>(),
              p.error_calibrated_mm / o.observation.noise_mm, 1e-12);
  // The HDF5 table has the fitted value and the truth beside each other.
  const TableFile t = read_table_file(o.out / "study.h5");
  auto column = [&](const std::string& name) -> const TableColumn* {
    for (const auto& c : t.columns)
      if (c.name == name) return &c;
    return nullptr;
  };
  ASSERT_NE(column("fitted_peak_pressure"), nullptr);
  ASSERT_NE(column("truth_peak_pressure"), nullptr);
  EXPECT_EQ(column("fitted_peak_pressure")->numbers.at(0), p.fitted["peak_pressure"].get<double>());
  EXPECT_EQ(column("truth_peak_pressure")->numbers.at(0), p.truth["peak_pressure"].get<double>());

  // One model for both: the reported error after calibration is the search's own.
  CohortStudyOptions same = quick(1);
  same.out = dir_ / "same";
  same.calibrate = true;
  same.fit = "restlength";
  same.max_simulations = 8;
  const CohortStudyResult s = run_cohort_study(same, *pool);
  ASSERT_EQ(s.patients[0].status, "ok") << s.patients[0].reason;
  // Rest-length recovery counts every fitted factor once, as identified or not, and a factor
  // within the tolerance of the truth as recovered.
  int factors = 0, identified = 0, within = 0;
  for (const auto& [name, v] : s.patients[0].fitted.items()) {
    ++factors;
    if (!s.patients[0].identified.value(name, false)) continue;
    ++identified;
    within += std::abs(v.get<double>() - s.patients[0].truth[name].get<double>()) <= 0.05;
  }
  EXPECT_GE(factors, 2);
  const json& rr = s.summary["calibration"]["restlength_recovery"];
  EXPECT_EQ(rr["identified"].get<int>() + rr["unidentified"].get<int>(), factors);
  EXPECT_EQ(rr["identified"].get<int>(), identified);
  EXPECT_EQ(rr["identified_within_tolerance"].get<int>(), within);
  EXPECT_EQ(s.patients[0].error_calibrated_mm, s.patients[0].error_calibrated_fit_model_mm);
  EXPECT_TRUE(s.patients[0].refinement.empty()) << s.patients[0].refinement;
  EXPECT_NEAR(s.patients[0].error_default_mm, s.patients[0].error_default_fit_model_mm, 1e-9);
}

TEST_F(CohortStudy, FolderWithOtherSettingsIsRefusedNamingThem) {
  CohortStudyOptions o = quick(1);
  auto pool = make_local_pool();
  run_cohort_study(o, *pool);
  o.model.dt = 0.01;
  try {
    run_cohort_study(o, *pool);
    FAIL() << "a folder holding another study was reused";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("calibration_model"), std::string::npos) << e.what();
  }
}

TEST_F(CohortStudy, BadPatientFileIsRecordedAndTheOthersGoOn) {
  // Two real-patient-style files: one observed virtual patient, one corrupt.
  CohortStudyOptions v = quick(1);
  auto pool = make_local_pool();
  run_cohort_study(v, *pool);
  fs::create_directories(dir_ / "folder");
  for (const auto& f : fs::directory_iterator(v.out / "observed"))
    fs::copy(f.path(), dir_ / "folder" / "a.h5");
  {
    std::ofstream bad(dir_ / "folder" / "b.h5");
    bad << "not an HDF5 file";
  }
  CohortStudyOptions o = quick(1);
  o.folder = dir_ / "folder";
  o.out = dir_ / "from_folder";
  const CohortStudyResult r = run_cohort_study(o, *pool);
  ASSERT_EQ(r.patients.size(), 2u);
  EXPECT_EQ(r.patients[0].status, "ok") << r.patients[0].reason;
  EXPECT_EQ(r.patients[1].status, "failed");
  EXPECT_NE(r.patients[1].reason.find("b.h5"), std::string::npos) << r.patients[1].reason;
  EXPECT_EQ(r.summary["overall"]["failed"].get<int>(), 1);
  // The same patient gives the same error read from a folder as in the virtual cohort.
  EXPECT_DOUBLE_EQ(
      r.patients[0].error_default_mm,
      read_json(v.out / "study.json")["patients"][0]["error_default_mm"].get<double>());
}

TEST(CohortStudyConfig, NormalValvesAreTunedByDefaultAndTheConfigSaysSo) {
  const CohortStudyOptions full;
  EXPECT_TRUE(full.observation.tune_normal_chordae);
  EXPECT_EQ(full.config()["normal_chordae_tuning"], forward::kChordaeTuningEdition);
  // The test size does not tune (13 closures at the paper's grid per normal valve).
  EXPECT_FALSE(CohortStudyOptions::quick().observation.tune_normal_chordae);
  EXPECT_TRUE(CohortStudyOptions::quick().config()["normal_chordae_tuning"].is_null());
}

TEST_F(CohortStudy, ATunedNormalValveIsObservedAnewAndTheSickOnesObservationIsShared) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "the tuning's closures take too long under AddressSanitizer";
#endif
  // Patient 0 is normal, 1 is not; one observation cache for both runs.
  CohortStudyOptions o = quick(2);
  o.cache = dir_ / "cache";
  auto pool = make_local_pool();
  run_cohort_study(o, *pool);
  auto files = [&] {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(o.cache))
      names.insert(e.path().filename().string());
    return names;
  };
  const std::set<std::string> untuned = files();
  ASSERT_EQ(untuned.size(), 2u);
  // The same study with the normal valve tuned (on a coarse model: seconds), in another folder.
  o.out = dir_ / "tuned";
  o.observation.tune_normal_chordae = true;
  o.observation.tuning.simulation = o.observation.simulation;
  o.observation.tuning.iterations = 1;
  run_cohort_study(o, *pool);
  const std::set<std::string> both = files();
  ASSERT_EQ(both.size(), 3u) << "only the normal valve's observation is made again";
  std::string tuned_file;
  for (const auto& n : both)
    if (!untuned.count(n)) tuned_file = n;
  EXPECT_NE(tuned_file.find("virtual-2026-0"), std::string::npos) << tuned_file;
  EXPECT_EQ(forward::tuning_edition(read_patient(o.cache / tuned_file, false)),
            forward::kChordaeTuningEdition);
  EXPECT_EQ(read_json(o.out / "study_config.json")["config"]["normal_chordae_tuning"],
            forward::kChordaeTuningEdition);
}

// The virtual patients' edition is part of the config: a folder of edition 2's patients (flails
// and functional MR drawn otherwise) is refused, not resumed with today's patients mixed in.
TEST_F(CohortStudy, AFolderOfAnotherPatientEditionIsRefused) {
  CohortStudyOptions o = quick(1);
  json old{{"study", "cohort"}, {"config", o.config()}};
  ASSERT_EQ(old["config"]["virtual_patient_edition"], kVirtualPatientEdition);
  old["config"]["virtual_patient_edition"] = kVirtualPatientEdition - 1;
  fs::create_directories(o.out);
  std::ofstream(o.out / "study_config.json") << old.dump(2);
  auto pool = make_local_pool();
  try {
    run_cohort_study(o, *pool);
    ADD_FAILURE() << "a folder of another patient edition was resumed";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("virtual_patient_edition"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(o.out / "study.json"));
}

TEST_F(CohortStudy, InvalidOptionsAreRefused) {
  auto pool = make_local_pool();
  CohortStudyOptions o = quick(1);
  o.patients = 0;
  EXPECT_THROW(run_cohort_study(o, *pool), Error);
  o = quick(1);
  o.out.clear();
  EXPECT_THROW(run_cohort_study(o, *pool), Error);
}

std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

TEST_F(CohortStudy, TwoMpiRanksGiveTheSingleProcessNumbers) {
#ifdef __SANITIZE_ADDRESS__
  // Eight observed closures (3.5 min); under mpirun the leak check is off anyway.
  GTEST_SKIP() << "eight closures take too long under AddressSanitizer";
#endif
  if (!built_with_mpi()) GTEST_SKIP() << "this build has no MPI (libopenmpi-dev not found)";
  if (std::system("command -v mpirun > /dev/null 2>&1") != 0)
    GTEST_SKIP() << "no mpirun on this machine";
  // Open MPI refuses root without these; its own allocations at exit are not ours to check.
  const std::string env =
      "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 "
      "OMPI_MCA_btl_vader_single_copy_mechanism=none "
      "ASAN_OPTIONS=detect_leaks=0 ";
  const std::string common =
      " study cohort --quick --patients 4 --jobs 1 --cache " + (dir_ / "obs").string();
  const std::string one = std::string(MVTWIN_BINARY) + common + " --out " + (dir_ / "one").string();
  const std::string two = env + "mpirun -np 2 --oversubscribe " + std::string(MVTWIN_BINARY) +
                          common + " --out " + (dir_ / "two").string();
  const std::string log = (dir_ / "log.txt").string();
  ASSERT_EQ(std::system((one + " > " + log + " 2>&1").c_str()), 0) << slurp(log);
  const int rc = std::system((two + " > " + log + " 2>&1").c_str());
  const std::string out = slurp(log);
  ASSERT_EQ(WEXITSTATUS(rc), 0) << out;
  EXPECT_NE(out.find("2 MPI ranks"), std::string::npos) << out;
  // Both ranks worked (dynamic balancing hands each at least one of 4 patients).
  EXPECT_NE(out.find("[rank 0]"), std::string::npos) << out;
  EXPECT_NE(out.find("[rank 1]"), std::string::npos) << out;
  EXPECT_EQ(numbers_of(read_json(dir_ / "two" / "study.json")),
            numbers_of(read_json(dir_ / "one" / "study.json")));
}

}  // namespace

namespace {

TEST(Scaling, DynamicBalancingMatchesHandCountedSchedules) {
  // Equal items that fill every rank: nobody waits.
  EXPECT_DOUBLE_EQ(dynamic_makespan(std::vector<double>(8, 2.0), 4), 4.0);
  EXPECT_DOUBLE_EQ(dynamic_efficiency(std::vector<double>(8, 2.0), 4), 1.0);
  // One item more than ranks: the last runs alone, (n+1)/(2n).
  EXPECT_DOUBLE_EQ(dynamic_efficiency(std::vector<double>(5, 1.0), 4), 5.0 / 8.0);
  // A long item first: the others fill the second rank (3 | 1+1+1).
  EXPECT_DOUBLE_EQ(dynamic_makespan({3, 1, 1, 1}, 2), 3.0);
  // A long item last waits for a free rank: (1+1 | 1), then 3 on the rank free at 1.
  EXPECT_DOUBLE_EQ(dynamic_makespan({1, 1, 1, 3}, 2), 4.0);
  EXPECT_DOUBLE_EQ(dynamic_makespan({1, 2, 3}, 1), 6.0);
  // Many patients per rank: efficiency tends to 1 whatever the spread.
  const std::vector<double> spread{10, 30, 60, 45, 20};
  EXPECT_GT(expected_efficiency(spread, 10000, 10), 0.99);
  EXPECT_LT(expected_efficiency(spread, 100, 100), 0.6);  // one patient each: the longest decides
  EXPECT_THROW(expected_efficiency({}, 10, 2), Error);
  EXPECT_THROW(dynamic_makespan({1.0}, 0), Error);
}

}  // namespace
