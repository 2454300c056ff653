#pragma once
// mvtwin calibrate: fits chordae rest lengths, stiffnesses and pressure to a patient's observed
// closed valve (inverse/calibration.h).
#include <string>
#include <vector>

#include "command.h"
#include "mvtwin/inverse/calibration.h"

namespace mvtwin::tools {

struct CalibrateArgs : CommandArgs {
  std::string file;
  std::string out;  ///< calibration file (HDF5); a .json summary is written beside it
  std::string vtk;  ///< directory for the valve before and after; "" = none
  std::string fit = "restlength,stiffness,pressure";
  bool force = false;
  bool all_frames = false;    ///< every observed closing frame, not only the first closed one
  bool use_detected = false;  ///< the sequence detected from the images (mvtwin detect)
  inverse::CalibrationOptions calibration;
  std::vector<std::string> sets;  ///< name=value for the calibration model
  /// name=value for the search model, on top of the default one (inverse::search_model_for: 24
  /// x 24 for the paper's grid); no_search_model: the optimizer runs on the calibration model.
  std::vector<std::string> search_sets;
  bool no_search_model = false;
};

int run_calibrate(const CalibrateArgs& args);
void register_calibrate(CLI::App& app, Context& ctx);

/// The fit options of calibrate: --jobs, --max-sims, --scan, --no-scan.
void add_fit_options(CLI::App* cmd, inverse::CalibrationOptions* options);
/// --method METHOD (bobyqa | cobyla | neldermead | sbplx | ceres) into *method; an unknown name
/// is a usage error that lists the known ones.
CLI::Option* add_method_option(CLI::App* cmd, inverse::FitMethod* method);

}  // namespace mvtwin::tools
