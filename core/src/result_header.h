#pragma once
// Internal: the root of mvtwin's result files (simulation, calibration): format tag and version,
// the patient, whether it is synthetic, provenance, and the `name=value` options that produced
// the result. One writer and one reader so that the formats cannot drift apart.
#include <string>
#include <utility>
#include <vector>

#include "hdf5_io.h"
#include "mvtwin/core/patient.h"

namespace mvtwin::h5 {

struct ResultHeader {
  std::string patient_id, patient_file;
  bool synthetic = false;
  Provenance provenance;
  std::vector<std::pair<std::string, std::string>> options;
};

/// `kind` names the result in the data_origin attribute ("simulation", "calibration").
void write_result_header(const Location& root, const char* format, long format_version,
                         const char* kind, const ResultHeader& h);
/// Checks the format tag and version (naming `kind` in the error) and reads the header.
ResultHeader read_result_header(const Location& root, const char* format, long format_version,
                                const char* kind);

}  // namespace mvtwin::h5
