#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/forward/closure_scene.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::forward {

/// Writes the closure scene at end-diastole so that another solver can run it
/// (docs/valve-model.md, docs/febio-export.md):
///   leaflets.vtu            corner tetrahedra: tag, fibre, per point `prescribed`
///   leaflets_quadratic.vtu  the elements as simulated (VTK_QUADRATIC_TETRA or VTK_TETRA)
///   chordae.vtp             insertion-to-tip lines: group, marginal, end-diastolic and rest
///                           length, the law (A0, E low / high, strain at the break), tip
///   pressure_surface.vtp    the ventricular faces where the pressure acts
///   boundary.csv            per time sample: pressure (MPa) and both papillary tips (mm)
///   annulus_motion.csv      per time sample and prescribed node: its position (mm)
///   boundary.pvd            the annulus curve and tips over time for ParaView
///   valve.feb               the same scene for FEBio (forward/febio_export.h)
/// `comment` (provenance) heads the text files. Returns the files written.
std::vector<std::filesystem::path> export_scene(const ClosureScene& scene,
                                                const ClosureOptions& options,
                                                const std::filesystem::path& dir,
                                                const std::string& comment,
                                                const std::vector<int>& guarded = {});

/// Writes a simulation's recorded atrial surfaces as la_surface_NNNN.vtp plus a time series
/// simulation.pvd (simulated time). Returns the files written.
std::vector<std::filesystem::path> export_closure_vtk(const ClosureResult& result,
                                                      const std::filesystem::path& dir);

}  // namespace mvtwin::forward
