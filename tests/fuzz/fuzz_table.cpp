// A study's table file (HDF5), which resumed studies read back.
#include "fuzz_input.h"
#include "mvtwin/core/table_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return mvtwin::fuzz::read_bytes(data, size, ".h5",
                                  [](const auto& p) { mvtwin::read_table_file(p); });
}
