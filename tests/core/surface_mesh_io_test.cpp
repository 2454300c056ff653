#include "mvtwin/core/surface_mesh_io.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "mvtwin/core/error.h"

namespace mvtwin {
namespace {

namespace fs = std::filesystem;

fs::path mesh_temp(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / "mvtwin_surface_mesh_test";
  fs::create_directories(d);
  return d / name;
}

TriangleMesh tetra_surface() {  // a closed tetrahedron's surface, 4 vertices, 4 triangles
  TriangleMesh m;
  m.V.resize(4, 3);
  m.V << 0.125, 0, 10, 20.5, 0, 10, 0, 30.25, 10, 0, 0, -5.75;
  m.F.resize(4, 3);
  m.F << 0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2;
  return m;
}

TEST(SurfaceMesh, EveryFormatRoundTrips) {
  const TriangleMesh m = tetra_surface();
  for (const char* name : {"t.stl", "t.ply", "t.vtk", "t.vtp", "t_raw.vtp"}) {
    const fs::path p = mesh_temp(name);
    write_surface_mesh(p, m, "LPS", std::string(name) != "t_raw.vtp");
    const SurfaceFile r = read_surface_mesh(p);
    EXPECT_EQ(r.space, "LPS") << name;
    ASSERT_EQ(r.mesh.V.rows(), 4) << name;  // STL corners merged back into 4 vertices
    ASSERT_EQ(r.mesh.F.rows(), 4) << name;
    for (Eigen::Index f = 0; f < 4; ++f)
      for (int k = 0; k < 3; ++k)
        EXPECT_TRUE(r.mesh.V.row(r.mesh.F(f, k)).isApprox(m.V.row(m.F(f, k)), 1e-6)) << name;
  }
}

// Files as other tools write them, by hand.
TEST(SurfaceMesh, HandWrittenFiles) {
  auto write = [](const fs::path& p, const std::string& t) {
    std::ofstream(p, std::ios::binary) << t;
  };
  write(mesh_temp("a.stl"),
        "solid SPACE=RAS\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n   "
        "vertex 0 1 0\n"
        "  endloop\n endfacet\n facet normal 0 0 1\n  outer loop\n   vertex 1 0 0\n   vertex 1 1 "
        "0\n   vertex 0 1 0\n"
        "  endloop\n endfacet\nendsolid\n");
  SurfaceFile s = read_surface_mesh(mesh_temp("a.stl"));
  EXPECT_EQ(s.space, "RAS");
  EXPECT_EQ(s.mesh.V.rows(), 4);
  EXPECT_EQ(s.mesh.F.rows(), 2);
  // VTK 5.1's layout (OFFSETS / CONNECTIVITY), a quad fanned into two triangles.
  write(mesh_temp("q.vtk"),
        "# vtk DataFile Version 5.1\nquad\nASCII\nDATASET POLYDATA\nPOINTS 4 float\n0 0 0 1 0 0 1 "
        "1 0 0 1 0\n"
        "POLYGONS 2 4\nOFFSETS vtktypeint64\n0 4\nCONNECTIVITY vtktypeint64\n0 1 2 3\n");
  s = read_surface_mesh(mesh_temp("q.vtk"));
  EXPECT_EQ(s.mesh.F.rows(), 2);
  EXPECT_EQ(s.space, "");
  // Binary little-endian PLY with an extra vertex property and a uint8/int32 face list.
  {
    std::string t =
        "ply\nformat binary_little_endian 1.0\ncomment SPACE=LPS\nelement vertex 3\nproperty float "
        "x\nproperty float y\n"
        "property float z\nproperty uchar red\nelement face 1\nproperty list uchar int "
        "vertex_indices\nend_header\n";
    const float v[9] = {0, 0, 0, 2, 0, 0, 0, 3, 0};
    for (int i = 0; i < 3; ++i) {
      t.append(reinterpret_cast<const char*>(v + 3 * i), 12);
      t += '\x7f';
    }
    t += '\x03';
    const int f[3] = {0, 1, 2};
    t.append(reinterpret_cast<const char*>(f), 12);
    write(mesh_temp("b.ply"), t);
    s = read_surface_mesh(mesh_temp("b.ply"));
    EXPECT_EQ(s.space, "LPS");
    EXPECT_EQ(s.mesh.V(2, 1), 3.0);
  }
}

TEST(SurfaceMesh, BadFilesAreNamed) {
  auto expect = [](const std::string& name, const std::string& text, const std::string& part) {
    const fs::path p = mesh_temp(name);
    std::ofstream(p, std::ios::binary) << text;
    try {
      read_surface_mesh(p);
      FAIL() << "expected an error for " << name;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  expect("x.obj", "v 0 0 0\n", "unknown surface format");
  expect("junk.stl", "not an stl at all, and not of a binary size", "neither an ASCII STL");
  expect("range.vtk",
         "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0 1 0 0 0 1 "
         "0\nPOLYGONS 1 4\n3 0 1 7\n",
         "refers to vertex 7");
  // A line of whitespace that is not trimmed (a vertical tab) is skipped like a blank one
  // (fuzz_surface_mesh: it was read as a keyword from an empty word list).
  expect("vtab.vtk",
         "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\n\v\nPOINTS 3 float\n0 0 0 1 0 0 "
         "0 1 0\nPOLYGONS 1 4\n3 0 1 7\n",
         "refers to vertex 7");
  expect("grid.vtk", "# vtk DataFile Version 3.0\nx\nASCII\nDATASET STRUCTURED_POINTS\n",
         "not POLYDATA");
  expect("short.vtk",
         "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0 1\n",
         "ends early");
  expect("nan.ply",
         "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty "
         "float z\nelement face 1\n"
         "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n",
         "NaN/Inf");
  expect("empty.vtp",
         "<VTKFile type=\"PolyData\"><PolyData><Piece NumberOfPoints=\"0\" "
         "NumberOfPolys=\"0\"><Points>"
         "<DataArray type=\"Float32\" NumberOfComponents=\"3\" "
         "format=\"ascii\"></DataArray></Points></Piece></PolyData></VTKFile>",
         "no triangles");
  // A <DataArray without its '>' restarted the search from the beginning for ever.
  expect("open.vtp",
         "<VTKFile type=\"PolyData\"><PolyData><Piece NumberOfPoints=\"3\" "
         "NumberOfPolys=\"1\"><Points><DataArray type",
         "not closed by '>'");
  expect("unclosed.vtp",
         "<VTKFile type=\"PolyData\"><PolyData><Piece NumberOfPoints=\"3\" "
         "NumberOfPolys=\"1\"><Points><DataArray type=\"Float32\">0 0 0",
         "has no </DataArray>");
  expect("image.vtp", "<VTKFile type=\"ImageData\"></VTKFile>", "not VTK PolyData");
  // Numbers that no integer holds (found by fuzz_surface_mesh: casting them was undefined
  // behaviour) are refused by name.
  expect("huge.vtk",
         "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0 1 0 0 0 1 "
         "0\nPOLYGONS 1 4\n3 0 1 1e300\n",
         "not a whole number");
  expect("huge.ply",
         "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty "
         "float z\nelement face 1\n"
         "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 -4e18\n",
         "not a whole number");
  expect("offsets.vtp",
         "<VTKFile type=\"PolyData\"><PolyData><Piece NumberOfPoints=\"3\" "
         "NumberOfPolys=\"1\"><Points>"
         "<DataArray type=\"Float32\" NumberOfComponents=\"3\" "
         "format=\"ascii\">0 0 0 1 0 0 0 1 0</DataArray></Points><Polys>"
         "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">0 1 2</DataArray>"
         "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">-5.5e8</DataArray>"
         "</Polys></Piece></PolyData></VTKFile>",
         "not a whole number");
  EXPECT_THROW(read_surface_mesh(mesh_temp("missing.stl")), Error);
}

}  // namespace
}  // namespace mvtwin
