#pragma once
#include <filesystem>

#include "mvtwin/core/patient.h"

namespace mvtwin {

/// Format name and version written in the root attributes of a patient file.
inline constexpr const char* kPatientFormat = "mvtwin-patient";
inline constexpr int kPatientFormatVersion = 1;

/// Writes a patient to an HDF5 file (layout: docs/patient-file.md), atomically. The sequence is
/// validated first. Throws mvtwin::Error naming the file and the problem.
void write_patient(const std::filesystem::path& path, const Patient& patient);

/// Reads and validates a patient file. Throws mvtwin::Error naming the file, the dataset and
/// the problem for a missing, truncated or non-HDF5 file, a missing dataset, a wrong shape,
/// a NaN where a value is required, or times out of order.
/// `with_images` false skips the image volumes (they can be large).
Patient read_patient(const std::filesystem::path& path, bool with_images = true);

/// The current UTC time as ISO 8601, for Provenance::created_utc.
std::string utc_now_iso8601();

}  // namespace mvtwin
