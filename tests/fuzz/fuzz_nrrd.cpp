// NRRD (attached data: raw, gzip or ascii; 3D, 3D+t sequences) and, when the header is a 3D
// Slicer segmentation's, the segment merging `import` does with it.
#include <map>
#include <string>

#include "fuzz_input.h"
#include "mvtwin/core/image_io.h"
#include "mvtwin/detection/segmentation_labels.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return mvtwin::fuzz::read_bytes(data, size, ".nrrd", [](const auto& p) {
    std::map<std::string, std::string> fields;
    const auto volumes = mvtwin::read_nrrd_series(p, &fields);
    if (mvtwin::detection::is_slicer_segmentation(fields))
      mvtwin::detection::slicer_segmentation(volumes, fields, p.string());
  });
}
