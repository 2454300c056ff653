#include "mvtwin/core/calibration_file.h"

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "../support/sample_records.h"
#include "mvtwin/core/error.h"

namespace mvtwin {
namespace {

namespace fs = std::filesystem;

CalibrationRecord sample() { return test_support::sample_calibration_record(); }

fs::path calibration_temp(const std::string& name) {
  return fs::temp_directory_path() / ("mvtwin_calib_" + std::to_string(getpid()) + "_" + name);
}

TEST(CalibrationFile, RoundTrip) {
  const CalibrationRecord a = sample();
  const fs::path p = calibration_temp("rt.h5");
  write_calibration_file(p, a);
  const CalibrationRecord b = read_calibration_file(p);
  fs::remove(p);
  EXPECT_EQ(b.patient_id, a.patient_id);
  EXPECT_TRUE(b.synthetic);
  EXPECT_EQ(b.provenance.seed, 3u);
  EXPECT_EQ(b.options, a.options);
  EXPECT_EQ(b.names, a.names);
  EXPECT_EQ(b.units, a.units);
  EXPECT_EQ(b.identified, a.identified);
  EXPECT_EQ(b.fitted, a.fitted);
  EXPECT_TRUE(std::isnan(b.sd[1]));
  EXPECT_EQ(b.covariance, a.covariance);
  EXPECT_EQ(b.history_x, a.history_x);
  EXPECT_TRUE(std::isnan(b.history_error_mm[1]));
  EXPECT_DOUBLE_EQ(b.parameters.restlength_factor[0], 1.12);
  EXPECT_EQ(b.failed_simulations, 1);
  EXPECT_DOUBLE_EQ(b.error_after_mm, 0.6);
  // Searched on the fit's model: no search figures.
  EXPECT_EQ(b.search_simulations, 0);
  EXPECT_TRUE(std::isnan(b.search_error_before_mm));
  EXPECT_TRUE(std::isnan(b.search_error_after_mm));
  EXPECT_TRUE(b.refinement.empty());
}

TEST(CalibrationFile, ASearchModelsFiguresRoundTrip) {
  CalibrationRecord a = sample();
  a.options.emplace_back("fit_search_model", "ures=24,vres=24");
  a.search_simulations = 2;
  a.search_error_before_mm = 1.4;
  a.search_error_after_mm = 0.55;
  a.refinement = "Gauss-Newton step kept (damping 0.3): 0.62 -> 0.60 mm on the 30 x 30 model";
  const fs::path p = calibration_temp("search.h5");
  write_calibration_file(p, a);
  const CalibrationRecord b = read_calibration_file(p);
  fs::remove(p);
  EXPECT_EQ(b.options, a.options);
  EXPECT_EQ(b.search_simulations, 2);
  EXPECT_EQ(b.search_error_before_mm, 1.4);
  EXPECT_EQ(b.search_error_after_mm, 0.55);
  EXPECT_EQ(b.refinement, a.refinement);
}

TEST(CalibrationFile, InconsistentRecordIsRefusedAndTheOldFileKept) {
  const fs::path p = calibration_temp("keep.h5");
  write_calibration_file(p, sample());
  CalibrationRecord bad = sample();
  bad.sd.resize(1);
  EXPECT_THROW(write_calibration_file(p, bad), Error);
  EXPECT_NO_THROW(read_calibration_file(p)) << "the earlier file is untouched";
  fs::remove(p);
}

TEST(CalibrationFile, OtherFilesAreNamedAsSuch) {
  const fs::path p = calibration_temp("not.h5");
  { std::ofstream(p) << "not hdf5"; }
  EXPECT_THROW(read_calibration_file(p), Error);
  fs::remove(p);
  EXPECT_THROW(read_calibration_file(calibration_temp("missing.h5")), Error);
}

}  // namespace
}  // namespace mvtwin
