#include "mvtwin/core/vtk_writer.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_vtk.h"
#include "mvtwin/core/virtual_patient.h"

namespace mvtwin {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

bool have_python_vtk() {
  return std::system("/usr/bin/python3 -c 'import vtk' > /dev/null 2>&1") == 0;
}

// Reads a VTK XML file with VTK's own reader (what ParaView uses) and prints
// "<points> <cells> <array names>"; empty if VTK is not available.
std::string read_with_vtk(const fs::path& p) {
  const fs::path out = p.string() + ".check";
  const std::string reader =
      p.extension() == ".vtu" ? "vtkXMLUnstructuredGridReader" : "vtkXMLPolyDataReader";
  const std::string cmd =
      "/usr/bin/python3 -c \"import vtk,sys\nr=vtk." + reader + "()\nr.SetFileName('" + p.string() +
      "')\nr.Update()\no=r.GetOutput()\nn=[o.GetCellData().GetArrayName(i) for i in "
      "range(o.GetCellData().GetNumberOfArrays())]"
      "+[o.GetPointData().GetArrayName(i) for i in range(o.GetPointData().GetNumberOfArrays())]\n"
      "print(o.GetNumberOfPoints(), o.GetNumberOfCells(), ' '.join(n))\" > " +
      out.string() + " 2>&1";
  if (std::system(cmd.c_str()) != 0) return "python failed: " + slurp(out);
  return slurp(out);
}

class VtkWriter : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("mvtwin_vtk_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    mesh_.V.resize(5, 3);
    mesh_.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1;
    mesh_.T.resize(2, 4);
    mesh_.T << 0, 1, 2, 3, 1, 2, 3, 4;
    mesh_.tag.resize(2);
    mesh_.tag << 1, 2;
    mesh_.fibre.resize(2, 3);
    mesh_.fibre << 1, 0, 0, 0, 1, 0;
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
  TetMesh mesh_;
};

TEST_F(VtkWriter, TetMeshVtuHasCellsTagsAndFibres) {
  ASSERT_GT(mesh_.volume(0), 0);
  if (mesh_.volume(1) < 0) std::swap(mesh_.T(1, 0), mesh_.T(1, 1));
  write_vtu(dir_ / "m.vtu", mesh_, {}, {{"strain", 1, {0.1, 0.2}, false}});
  const std::string s = slurp(dir_ / "m.vtu");
  EXPECT_NE(s.find("NumberOfPoints=\"5\" NumberOfCells=\"2\""), std::string::npos);
  EXPECT_NE(s.find("Name=\"tag\""), std::string::npos);
  EXPECT_NE(s.find("Name=\"fibre\" NumberOfComponents=\"3\""), std::string::npos);
  if (!have_python_vtk()) GTEST_SKIP() << "python3-vtk9 absent: VTK reader cross-check skipped";
  EXPECT_EQ(read_with_vtk(dir_ / "m.vtu"), "5 2 tag fibre strain\n");
}

TEST_F(VtkWriter, RefusesBadMeshes) {
  TetMesh inverted = mesh_;
  std::swap(inverted.T(0, 0), inverted.T(0, 1));
  EXPECT_THROW(write_vtu(dir_ / "bad.vtu", inverted), Error);
  TetMesh nan = mesh_;
  nan.V(2, 1) = std::nan("");
  EXPECT_THROW(write_vtu(dir_ / "bad.vtu", nan), Error);
  EXPECT_THROW(write_vtp(dir_ / "bad.vtp", TriangleMesh{mesh_.V, Eigen::Matrix<int, 1, 3>(0, 1, 2)},
                         {{"x", 1, {1.0, 2.0}, false}}),  // 2 values for 5 points
               Error);
  EXPECT_FALSE(fs::exists(dir_ / "bad.vtu"));
  EXPECT_FALSE(fs::exists(dir_ / "bad.vtp"));
}

TEST_F(VtkWriter, PatientSeriesOpensInVtk) {
  const Patient p = make_virtual_patient(3);
  const auto files = export_patient_vtk(p, dir_ / "series");
  EXPECT_EQ(files.size(), static_cast<size_t>(3 * p.sequence.num_frames() + 3));
  const std::string pvd = slurp(dir_ / "series" / "la_surface.pvd");
  // One DataSet per frame, with the frame time.
  int n = 0;
  for (size_t at = pvd.find("<DataSet timestep=\""); at != std::string::npos;
       at = pvd.find("<DataSet timestep=\"", at + 1)) {
    ++n;
  }
  EXPECT_EQ(n, p.sequence.num_frames());
  if (!have_python_vtk()) GTEST_SKIP() << "python3-vtk9 absent: VTK reader cross-check skipped";
  const int U = p.sequence.ures, V = p.sequence.vres;
  EXPECT_EQ(read_with_vtk(dir_ / "series" / "la_surface_0000.vtp"),
            std::to_string(U * V) + " " + std::to_string(2 * U * (V - 1)) + " leaflet u v\n");
  EXPECT_EQ(read_with_vtk(dir_ / "series" / "annulus_0000.vtp"), std::to_string(U) + " 1 u\n");
  // A closed frame (leaflets not observed) is an empty surface, not a stale one.
  char name[64];
  std::snprintf(name, sizeof name, "la_surface_%04d.vtp", p.sequence.first_closed);
  EXPECT_EQ(read_with_vtk(dir_ / "series" / name), "0 0 \n");
}

}  // namespace
}  // namespace mvtwin
