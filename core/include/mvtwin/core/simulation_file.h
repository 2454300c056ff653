#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/leaflet_grid.h"
#include "mvtwin/core/patient.h"
#include "mvtwin/core/regurgitant_orifice.h"
#include "mvtwin/core/tet_mesh.h"
#include "mvtwin/core/valve_parameters.h"

namespace mvtwin {

/// A closure simulation result as stored on disk (docs/simulation-file.md): what produced it,
/// the recorded atrial surfaces over time, the closure measures, and the final FE state with
/// per-element strain and stress.
struct SimulationRecord {
  std::string patient_id;
  std::string patient_file;
  bool synthetic = false;  ///< the simulated patient is a virtual one
  Provenance provenance;   ///< version, command, time; seed of the patient when synthetic
  std::vector<std::pair<std::string, std::string>> options;  ///< every simulation option
  ValveParameters parameters;
  std::string status;  ///< "converged" or "failed"
  /// The typed outcome (core/outcome.h: converged, inverted_element, leaflet_crossing, ...);
  /// empty in files written before it was recorded.
  std::string outcome;
  std::string reason;                                   ///< why it failed
  std::vector<std::pair<std::string, double>> summary;  ///< steps, timings, contacts, ...
  /// The static solve's residual (N) at its start and after each Newton iteration, and why it
  /// did not converge (empty when it did); group `static_solve`, absent when the run had none
  /// (and in files of older versions).
  std::vector<double> static_residual_n;
  std::string static_failure;

  // Time series (one entry per recorded sample; the last is the end state).
  std::vector<double> time_s, observed_time_s, anterior_tip_mm, posterior_tip_mm, orifice_area_mm2,
      annulus_area_mm2;
  std::vector<LeafletGrid> la_surface;  ///< atrial surface per sample, same grid

  // End state: the corner (linear) mesh at rest with tags and fibres, its nodes at the end,
  // and per element the largest principal co-rotational strain and the von Mises stress.
  TetMesh mesh;
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> final_positions;
  Eigen::VectorXd element_strain, element_stress_mpa;

  /// The closed valve's regurgitant orifice and the fine atrial and ventricular surfaces it was
  /// measured on (group `orifice`; absent in files of failed simulations and of older versions).
  std::optional<RegurgitantOrifice> orifice;
  LeafletGrid orifice_surface, orifice_lv_surface;
};

/// Writes atomically (a temporary file renamed over `path`). Throws mvtwin::Error.
void write_simulation_file(const std::filesystem::path& path, const SimulationRecord& r);
/// Reads a file written by write_simulation_file; throws mvtwin::Error naming the problem.
SimulationRecord read_simulation_file(const std::filesystem::path& path);
/// The root "format" attribute of an mvtwin HDF5 file ("mvtwin-patient", "mvtwin-simulation"),
/// empty when there is none. Throws if the file cannot be opened as HDF5.
std::string mvtwin_file_format(const std::filesystem::path& path);

}  // namespace mvtwin
