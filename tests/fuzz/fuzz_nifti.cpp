// NIfTI-1 (.nii, gzip-compressed or not: the reader opens both alike), through the reader
// `import`, `detect` and `info` use for images.
#include "fuzz_input.h"
#include "mvtwin/core/image_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return mvtwin::fuzz::read_bytes(data, size, ".nii",
                                  [](const auto& p) { mvtwin::read_image_series(p); });
}
