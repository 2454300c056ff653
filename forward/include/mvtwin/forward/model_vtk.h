#pragma once
#include <filesystem>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/forward/closure_simulation.h"
#include "mvtwin/forward/valve_model.h"

namespace mvtwin::forward {

/// Writes the model for ParaView: leaflets.vtu (corner tetrahedra with tag, fibre, and per
/// point the flag `prescribed`), chordae.vtp (lines from insertion to papillary tip with group,
/// marginal flag and end-diastolic length), pressure_surface.vtp (the ventricular faces).
/// Returns the files written.
std::vector<std::filesystem::path> export_model_vtk(const ValveModel& model,
                                                    const std::filesystem::path& dir);

/// Writes a simulation's recorded atrial surfaces as la_surface_NNNN.vtp plus a time series
/// simulation.pvd (simulated time). Returns the files written.
std::vector<std::filesystem::path> export_closure_vtk(const ClosureResult& result,
                                                      const std::filesystem::path& dir);

}  // namespace mvtwin::forward
