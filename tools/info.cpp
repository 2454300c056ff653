// mvtwin info (tools/info.h).
#include "info.h"

#include <iostream>

#include "exit_codes.h"
#include "mvtwin/core/calibration_file.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/simulation_file.h"
#include "report.h"

namespace mvtwin::tools {

int run_info(const InfoArgs& a) {
  if (mvtwin_file_format(a.file) == "mvtwin-simulation") {
    print_simulation_record(read_simulation_file(a.file), std::cout);
    return kExitOk;
  }
  if (mvtwin_file_format(a.file) == "mvtwin-calibration") {
    print_calibration(read_calibration_file(a.file), std::cout);
    return kExitOk;
  }
  print_patient(read_patient(a.file, true), std::cout);
  return kExitOk;
}

void register_info(CLI::App& app, Context& ctx) {
  auto* cmd =
      app.add_subcommand("info", "Human summary of a patient, simulation or calibration file");
  cmd->footer(
      "Examples:\n  mvtwin info patient.h5\n  mvtwin info closed.h5\n  mvtwin info calib.h5");
  auto a = std::make_shared<InfoArgs>();
  cmd->add_option("FILE", a->file, "patient, simulation or calibration file (HDF5)")->required();
  run_on_parse(cmd, ctx, a, run_info);
}

}  // namespace mvtwin::tools
