// The simulation result file (HDF5).
#include "fuzz_input.h"
#include "mvtwin/core/simulation_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return mvtwin::fuzz::read_bytes(data, size, ".h5",
                                  [](const auto& p) { mvtwin::read_simulation_file(p); });
}
