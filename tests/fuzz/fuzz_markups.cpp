// 3D Slicer markups: .mrk.json and .fcsv (the first byte picks which).
#include "fuzz_input.h"
#include "mvtwin/core/markups.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const char* const kEndings[] = {".mrk.json", ".fcsv"};
  return mvtwin::fuzz::read_bytes_as_one_of(data, size, kEndings,
                                            [](const auto& p) { mvtwin::read_markups(p); });
}
