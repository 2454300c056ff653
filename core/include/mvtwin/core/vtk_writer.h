#pragma once
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/tet_mesh.h"
#include "mvtwin/core/triangle_mesh.h"

namespace mvtwin {

/// A named data array attached to points or cells of a VTK file.
/// `values` holds components*n numbers, interleaved (x0 y0 z0 x1 ...).
struct VtkArray {
  std::string name;
  int components = 1;
  std::vector<double> values;
  bool integer = false;  ///< written as Int32 (tags, indices) instead of Float64
};

/// Geometry of a .vtp file: points plus any of vertices, lines and polygons.
struct VtkPolyData {
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> points;
  std::vector<std::vector<int>> verts;  ///< each a list of point indices
  std::vector<std::vector<int>> lines;  ///< polylines
  std::vector<std::vector<int>> polys;  ///< polygons (triangles)
  std::vector<VtkArray> point_data;
  std::vector<VtkArray> cell_data;  ///< one value per cell, cells counted verts, lines, polys
};

/// VTK XML PolyData (.vtp), ASCII, written atomically. Opens in ParaView and 3D Slicer.
void write_vtp(const std::filesystem::path& path, const VtkPolyData& data);

/// A triangle surface as .vtp.
void write_vtp(const std::filesystem::path& path, const TriangleMesh& mesh,
               const std::vector<VtkArray>& point_data = {},
               const std::vector<VtkArray>& cell_data = {});

/// VTK XML UnstructuredGrid (.vtu) of a tet mesh with its tags ("tag") and fibres ("fibre")
/// as cell data, plus any extra arrays.
void write_vtu(const std::filesystem::path& path, const TetMesh& mesh,
               const std::vector<VtkArray>& point_data = {},
               const std::vector<VtkArray>& cell_data = {});

/// A generic unstructured grid of cells of one VTK type (10 VTK_TETRA, 24 VTK_QUADRATIC_TETRA,
/// ...), each cell its point indices in VTK order.
struct VtkUnstructuredGrid {
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> points;
  std::vector<std::vector<int>> cells;
  int cell_type = 10;
  std::vector<VtkArray> point_data;
  std::vector<VtkArray> cell_data;
};
/// VTK XML UnstructuredGrid (.vtu) of a generic grid; throws for indices out of range.
void write_vtu(const std::filesystem::path& path, const VtkUnstructuredGrid& grid);

/// ParaView collection (.pvd) of a time series: (time in s, file path relative to the .pvd).
void write_pvd(const std::filesystem::path& path,
               const std::vector<std::pair<double, std::string>>& steps);

}  // namespace mvtwin
