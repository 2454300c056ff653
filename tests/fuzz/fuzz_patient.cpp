// The patient file (HDF5), images included.
#include "fuzz_input.h"
#include "mvtwin/core/patient_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return mvtwin::fuzz::read_bytes(data, size, ".h5",
                                  [](const auto& p) { mvtwin::read_patient(p, true); });
}
