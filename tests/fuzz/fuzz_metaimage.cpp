// MetaImage with its data in the file (.mha: raw or zlib-compressed, 3D or 3D+t).
#include "fuzz_input.h"
#include "mvtwin/core/image_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return mvtwin::fuzz::read_bytes(data, size, ".mha",
                                  [](const auto& p) { mvtwin::read_image_series(p); });
}
