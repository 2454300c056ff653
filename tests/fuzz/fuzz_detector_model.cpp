// The detector model file (OpenCV FileStorage YAML, plain or gzip-compressed: the first byte
// picks the ending).
#include "fuzz_input.h"
#include "mvtwin/detection/valve_detector.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const char* const kEndings[] = {".yml", ".yml.gz"};
  return mvtwin::fuzz::read_bytes_as_one_of(
      data, size, kEndings, [](const auto& p) { mvtwin::detection::ValveDetector::load(p); });
}
