#pragma once
#include <filesystem>
#include <vector>

#include "mvtwin/core/patient.h"

namespace mvtwin {

/// Writes a patient's sequence for ParaView: per frame the LA surface (.vtp with u, v grid
/// indices and the leaflet tag; an empty surface for frames whose leaflets are missing), the
/// annulus (closed polyline) and the observed landmarks (vertices with their index), plus one
/// .pvd time series per kind: la_surface.pvd, annulus.pvd, landmarks.pvd. Returns the paths
/// written. The directory is created if needed.
std::vector<std::filesystem::path> export_patient_vtk(const Patient& patient,
                                                      const std::filesystem::path& dir);

}  // namespace mvtwin
