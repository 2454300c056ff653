#include "mvtwin/core/simulation_file.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/virtual_patient.h"

namespace mvtwin {
namespace {

namespace fs = std::filesystem;

SimulationRecord sample_record() {
  const Patient p = make_virtual_patient(12);
  SimulationRecord r;
  r.patient_id = p.id;
  r.patient_file = "p.h5";
  r.synthetic = true;
  r.provenance.command = "test";
  r.provenance.seed = 12;
  r.options = {{"dt", "0.01"}, {"contact", "on"}};
  r.parameters.peak_pressure_mpa = 0.0123;
  r.parameters.restlength_factor[2] = 1.234;
  r.status = "converged";
  r.summary = {{"steps", 42}, {"wall_s", 1.5}};
  for (int s = 0; s < 3; ++s) {
    r.time_s.push_back(0.1 * s);
    r.observed_time_s.push_back(0.5 + 0.01 * s);
    r.anterior_tip_mm.push_back(-10 + s);
    r.posterior_tip_mm.push_back(-8 + s);
    r.orifice_area_mm2.push_back(200 - 90 * s);
    r.annulus_area_mm2.push_back(700);
    r.la_surface.push_back(*p.sequence.frames[s].la_surface);
  }
  r.mesh.V.resize(4, 3);
  r.mesh.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  r.mesh.T.resize(1, 4);
  r.mesh.T << 0, 1, 2, 3;
  r.mesh.tag.resize(1);
  r.mesh.tag << 1;
  r.mesh.fibre.resize(1, 3);
  r.mesh.fibre << 1, 0, 0;
  r.final_positions = r.mesh.V * 1.1;
  r.element_strain = Eigen::VectorXd::Constant(1, 0.1);
  r.element_stress_mpa = Eigen::VectorXd::Constant(1, 0.05);
  return r;
}

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
