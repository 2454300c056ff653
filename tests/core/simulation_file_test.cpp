#include "mvtwin/core/simulation_file.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "../support/sample_records.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/virtual_patient.h"

namespace mvtwin {
namespace {

namespace fs = std::filesystem;

SimulationRecord sample_record() { return test_support::sample_simulation_record(); }

TEST(SimulationFile, RoundTrip) {
  const fs::path f =
      fs::temp_directory_path() / ("mvtwin_sim_" + std::to_string(::getpid()) + ".h5");
  const SimulationRecord a = sample_record();
  write_simulation_file(f, a);
  EXPECT_EQ(mvtwin_file_format(f), "mvtwin-simulation");
  const SimulationRecord b = read_simulation_file(f);
  EXPECT_EQ(b.patient_id, a.patient_id);
  EXPECT_TRUE(b.synthetic);
  EXPECT_EQ(b.provenance.seed, 12u);
  EXPECT_EQ(b.options, a.options);
  EXPECT_EQ(b.status, "converged");
  EXPECT_DOUBLE_EQ(b.parameters.peak_pressure_mpa, 0.0123);
  EXPECT_DOUBLE_EQ(b.parameters.restlength_factor[2], 1.234);
  EXPECT_EQ(b.orifice_area_mm2, a.orifice_area_mm2);
  ASSERT_EQ(b.la_surface.size(), 3u);
  EXPECT_EQ(b.la_surface[2].points(), a.la_surface[2].points());
  EXPECT_EQ(b.final_positions, a.final_positions);
  EXPECT_EQ(b.mesh.T, a.mesh.T);
  EXPECT_DOUBLE_EQ(b.element_stress_mpa[0], 0.05);
  ASSERT_EQ(b.summary.size(), 2u);
  EXPECT_EQ(b.summary[0].first, "steps");
  fs::remove(f);
}

TEST(SimulationFile, BadFilesAreNamed) {
  const fs::path dir = fs::temp_directory_path() / ("mvtwin_simbad_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  // A patient file is not a simulation file.
  write_patient(dir / "p.h5", make_virtual_patient(13));
  try {
    read_simulation_file(dir / "p.h5");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not an mvtwin simulation file"), std::string::npos);
  }
  std::ofstream(dir / "junk.h5") << "not hdf5";
  EXPECT_THROW(read_simulation_file(dir / "junk.h5"), Error);
  EXPECT_THROW(read_simulation_file(dir / "missing.h5"), Error);
  // Inconsistent records are refused and nothing is left behind.
  SimulationRecord r = sample_record();
  r.orifice_area_mm2.pop_back();
  EXPECT_THROW(write_simulation_file(dir / "bad.h5", r), Error);
  EXPECT_FALSE(fs::exists(dir / "bad.h5"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mvtwin
