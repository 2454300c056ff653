// Surface meshes: STL, PLY, legacy VTK and VTK XML PolyData (the first byte picks which).
#include "fuzz_input.h"
#include "mvtwin/core/surface_mesh_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const char* const kEndings[] = {".stl", ".ply", ".vtk", ".vtp"};
  return mvtwin::fuzz::read_bytes_as_one_of(data, size, kEndings,
                                            [](const auto& p) { mvtwin::read_surface_mesh(p); });
}
