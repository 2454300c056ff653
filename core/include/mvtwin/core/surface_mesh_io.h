#pragma once
// Triangle surfaces from the tools of the field: STL (3D Slicer, most segmentation tools), PLY,
// VTK legacy polydata (.vtk) and VTK XML polydata (.vtp).
#include <filesystem>
#include <string>

#include "mvtwin/core/triangle_mesh.h"

namespace mvtwin {

struct SurfaceFile {
  TriangleMesh mesh;  ///< coordinates as in the file (polygons fanned into triangles)
  /// The space the file says it is in: "LPS" or "RAS" from 3D Slicer's "SPACE=..." header
  /// mark (STL header, VTK title, PLY comment, VTP field or comment), "" when it says nothing.
  std::string space;
};

/// Reads .stl (ASCII or binary; coincident corners merged so that triangles share vertices),
/// .ply (ASCII, binary little or big endian), .vtk (legacy POLYDATA, ASCII or BINARY; POLYGONS or
/// TRIANGLE_STRIPS, classic or OFFSETS/CONNECTIVITY layout), .vtp (XML PolyData; ascii, inline
/// base64 binary, raw or base64 appended data, optionally zlib-compressed). Throws mvtwin::Error
/// naming the file and the problem (unknown extension, truncated or malformed data, indices out
/// of range, non-finite coordinates, no triangles).
SurfaceFile read_surface_mesh(const std::filesystem::path& path);

/// Writes a surface (for exchange and tests): .stl (binary), .ply (ASCII), .vtk (legacy ASCII),
/// .vtp (XML, base64 binary, zlib-compressed when `compress`). `space` ("LPS", "RAS" or "")
/// is written as 3D Slicer's "SPACE=" mark; coordinates are written as given. Atomic.
void write_surface_mesh(const std::filesystem::path& path, const TriangleMesh& mesh,
                        const std::string& space = "", bool compress = true);

}  // namespace mvtwin
