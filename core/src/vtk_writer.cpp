#include "mvtwin/core/vtk_writer.h"

#include <cstdio>
#include <fstream>
#include <sstream>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/version.h"

namespace mvtwin {
namespace {

void write_text(const std::filesystem::path& path, const std::string& text) {
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    if (!f) throw Error(path.string() + ": cannot open for writing");
    f << text;
    f.flush();
    if (!f) throw Error(path.string() + ": write failed (disk full?)");
  });
}

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

void write_array(std::ostringstream& os, const VtkArray& a, size_t expected_tuples,
                 const std::string& where) {
  if (a.components < 1 || a.values.size() != expected_tuples * a.components) {
    throw Error("VTK array '" + a.name + "' on " + where + ": expected " +
                std::to_string(expected_tuples) + " tuples of " + std::to_string(a.components) +
                " components, got " + std::to_string(a.values.size()) + " values");
  }
  os << "        <DataArray type=\"" << (a.integer ? "Int32" : "Float64") << "\" Name=\"" << a.name
     << "\" NumberOfComponents=\"" << a.components << "\" format=\"ascii\">\n";
  for (size_t i = 0; i < a.values.size(); ++i) {
    os << (i % 12 == 0 ? "          " : " ")
       << (a.integer ? std::to_string(static_cast<long>(a.values[i])) : number(a.values[i]))
       << (i % 12 == 11 || i + 1 == a.values.size() ? "\n" : "");
  }
  os << "        </DataArray>\n";
}

void write_points(std::ostringstream& os,
                  const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>& P) {
  os << "      <Points>\n        <DataArray type=\"Float64\" NumberOfComponents=\"3\" "
        "format=\"ascii\">\n";
  for (Eigen::Index i = 0; i < P.rows(); ++i) {
    os << "          " << number(P(i, 0)) << " " << number(P(i, 1)) << " " << number(P(i, 2))
       << "\n";
  }
  os << "        </DataArray>\n      </Points>\n";
}

void write_data(std::ostringstream& os, const char* tag, const std::vector<VtkArray>& arrays,
                size_t n, const char* where) {
  if (arrays.empty()) return;
  os << "      <" << tag << ">\n";
  for (const VtkArray& a : arrays) write_array(os, a, n, where);
  os << "      </" << tag << ">\n";
}

void write_cells(std::ostringstream& os, const char* tag,
                 const std::vector<std::vector<int>>& cells, Eigen::Index n_points) {
  os << "      <" << tag
     << ">\n        <DataArray type=\"Int32\" Name=\"connectivity\" "
        "format=\"ascii\">\n          ";
  long offset = 0;
  std::vector<long> offsets;
  for (const auto& c : cells) {
    for (int i : c) {
      if (i < 0 || i >= n_points)
        throw Error("VTK cell refers to point " + std::to_string(i) + " of " +
                    std::to_string(n_points));
      os << i << " ";
    }
    offset += static_cast<long>(c.size());
    offsets.push_back(offset);
  }
  os << "\n        </DataArray>\n        <DataArray type=\"Int32\" Name=\"offsets\" "
        "format=\"ascii\">\n          ";
  for (long o : offsets) os << o << " ";
  os << "\n        </DataArray>\n      </" << tag << ">\n";
}

const char* kHeader = "<?xml version=\"1.0\"?>\n<!-- written by mvtwin ";

}  // namespace

void write_vtp(const std::filesystem::path& path, const VtkPolyData& d) {
  if (!d.points.allFinite()) throw Error(path.string() + ": refusing to write non-finite points");
  std::ostringstream os;
  os << kHeader << kVersion << " -->\n"
     << "<VTKFile type=\"PolyData\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
     << "  <PolyData>\n    <Piece NumberOfPoints=\"" << d.points.rows() << "\" NumberOfVerts=\""
     << d.verts.size() << "\" NumberOfLines=\"" << d.lines.size()
     << "\" NumberOfStrips=\"0\" NumberOfPolys=\"" << d.polys.size() << "\">\n";
  const size_t n_cells = d.verts.size() + d.lines.size() + d.polys.size();
  write_data(os, "PointData", d.point_data, static_cast<size_t>(d.points.rows()), "points");
  write_data(os, "CellData", d.cell_data, n_cells, "cells");
  write_points(os, d.points);
  if (!d.verts.empty()) write_cells(os, "Verts", d.verts, d.points.rows());
  if (!d.lines.empty()) write_cells(os, "Lines", d.lines, d.points.rows());
  if (!d.polys.empty()) write_cells(os, "Polys", d.polys, d.points.rows());
  os << "    </Piece>\n  </PolyData>\n</VTKFile>\n";
  write_text(path, os.str());
}

void write_vtp(const std::filesystem::path& path, const TriangleMesh& mesh,
               const std::vector<VtkArray>& point_data, const std::vector<VtkArray>& cell_data) {
  VtkPolyData d;
  d.points = mesh.V;
  d.polys.reserve(mesh.F.rows());
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    d.polys.push_back({mesh.F(f, 0), mesh.F(f, 1), mesh.F(f, 2)});
  d.point_data = point_data;
  d.cell_data = cell_data;
  write_vtp(path, d);
}

void write_vtu(const std::filesystem::path& path, const TetMesh& mesh,
               const std::vector<VtkArray>& point_data, const std::vector<VtkArray>& cell_data) {
  mesh.check(path.string().c_str());
  const auto n = static_cast<size_t>(mesh.T.rows());
  std::vector<VtkArray> cells = cell_data;
  VtkArray tag{"tag", 1, {}, true}, fibre{"fibre", 3, {}, false};
  for (size_t e = 0; e < n; ++e) {
    tag.values.push_back(mesh.tag[e]);
    for (int k = 0; k < 3; ++k) fibre.values.push_back(mesh.fibre(e, k));
  }
  cells.insert(cells.begin(), {tag, fibre});

  std::ostringstream os;
  os << kHeader << kVersion << " -->\n"
     << "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
     << "  <UnstructuredGrid>\n    <Piece NumberOfPoints=\"" << mesh.V.rows()
     << "\" NumberOfCells=\"" << n << "\">\n";
  write_data(os, "PointData", point_data, static_cast<size_t>(mesh.V.rows()), "points");
  write_data(os, "CellData", cells, n, "cells");
  write_points(os, mesh.V);
  os << "      <Cells>\n        <DataArray type=\"Int32\" Name=\"connectivity\" "
        "format=\"ascii\">\n";
  for (size_t e = 0; e < n; ++e) {
    os << "          " << mesh.T(e, 0) << " " << mesh.T(e, 1) << " " << mesh.T(e, 2) << " "
       << mesh.T(e, 3) << "\n";
  }
  os << "        </DataArray>\n        <DataArray type=\"Int32\" Name=\"offsets\" "
        "format=\"ascii\">\n          ";
  for (size_t e = 0; e < n; ++e) os << 4 * (e + 1) << (e % 16 == 15 ? "\n          " : " ");
  os << "\n        </DataArray>\n        <DataArray type=\"UInt8\" Name=\"types\" "
        "format=\"ascii\">\n          ";
  for (size_t e = 0; e < n; ++e) os << "10" << (e % 32 == 31 ? "\n          " : " ");  // VTK_TETRA
  os << "\n        </DataArray>\n      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n"
     << "</VTKFile>\n";
  write_text(path, os.str());
}

void write_vtu(const std::filesystem::path& path, const VtkUnstructuredGrid& g) {
  const auto np = static_cast<int>(g.points.rows());
  for (const auto& c : g.cells) {
    for (int i : c) {
      if (i < 0 || i >= np) throw Error(path.string() + ": cell point index out of range");
    }
  }
  if (!g.points.allFinite()) throw Error(path.string() + ": non-finite point coordinates");
  std::ostringstream os;
  os << kHeader << kVersion << " -->\n"
     << "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
     << "  <UnstructuredGrid>\n    <Piece NumberOfPoints=\"" << np << "\" NumberOfCells=\""
     << g.cells.size() << "\">\n";
  write_data(os, "PointData", g.point_data, static_cast<size_t>(np), "points");
  write_data(os, "CellData", g.cell_data, g.cells.size(), "cells");
  write_points(os, g.points);
  os << "      <Cells>\n        <DataArray type=\"Int32\" Name=\"connectivity\" "
        "format=\"ascii\">\n";
  for (const auto& c : g.cells) {
    os << "         ";
    for (int i : c) os << " " << i;
    os << "\n";
  }
  os << "        </DataArray>\n        <DataArray type=\"Int32\" Name=\"offsets\" "
        "format=\"ascii\">\n          ";
  size_t offset = 0;
  for (size_t e = 0; e < g.cells.size(); ++e) {
    offset += g.cells[e].size();
    os << offset << (e % 16 == 15 ? "\n          " : " ");
  }
  os << "\n        </DataArray>\n        <DataArray type=\"UInt8\" Name=\"types\" "
        "format=\"ascii\">\n          ";
  for (size_t e = 0; e < g.cells.size(); ++e)
    os << g.cell_type << (e % 32 == 31 ? "\n          " : " ");
  os << "\n        </DataArray>\n      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n"
     << "</VTKFile>\n";
  write_text(path, os.str());
}

void write_pvd(const std::filesystem::path& path,
               const std::vector<std::pair<double, std::string>>& steps) {
  std::ostringstream os;
  os << kHeader << kVersion << " -->\n"
     << "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
     << "  <Collection>\n";
  for (const auto& [t, file] : steps) {
    os << "    <DataSet timestep=\"" << number(t) << "\" group=\"\" part=\"0\" file=\"" << file
       << "\"/>\n";
  }
  os << "  </Collection>\n</VTKFile>\n";
  write_text(path, os.str());
}

}  // namespace mvtwin
