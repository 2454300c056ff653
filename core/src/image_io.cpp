#include "mvtwin/core/image_io.h"

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <string>

#include <Eigen/LU>

#include "mvtwin/core/error.h"
#include "mvtwin/core/nifti.h"

namespace mvtwin {
namespace {

enum class Format { kNifti, kNrrd, kMetaImage };

Format format_of(const std::filesystem::path& path) {
  std::string name = path.filename().string();
  std::transform(name.begin(), name.end(), name.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  auto ends = [&](const std::string& e) {
    return name.size() >= e.size() && name.compare(name.size() - e.size(), e.size(), e) == 0;
  };
  if (ends(".nii") || ends(".nii.gz")) return Format::kNifti;
  if (ends(".nrrd") || ends(".nhdr")) return Format::kNrrd;
  if (ends(".mha") || ends(".mhd")) return Format::kMetaImage;
  throw Error(path.string() +
              ": unknown image format (expected .nii, .nii.gz, .nrrd, .nhdr, .mha or .mhd)");
}

}  // namespace

std::vector<ImageVolume> read_image_series(const std::filesystem::path& path) {
  switch (format_of(path)) {
    case Format::kNifti:
      return read_nifti_series(path);
    case Format::kNrrd:
      return read_nrrd_series(path);
    case Format::kMetaImage:
      return read_metaimage_series(path);
  }
  return {};
}

ImageVolume read_image(const std::filesystem::path& path) {
  std::vector<ImageVolume> v = read_image_series(path);
  if (v.size() != 1) {
    throw Error(path.string() + ": expected a 3D image, found " + std::to_string(v.size()) +
                " frames");
  }
  return std::move(v.front());
}

void write_image_series(const std::filesystem::path& path, const std::vector<ImageVolume>& s) {
  static_assert(std::endian::native == std::endian::little,
                "the writers assume a little-endian host");
  const std::string what = path.string();
  const Format format = format_of(path);
  if (s.empty()) throw Error(what + ": no image to write");
  const ImageVolume& g = s.front();
  for (std::size_t f = 0; f < s.size(); ++f) {
    const ImageVolume& im = s[f];
    const std::string frame = " (frame " + std::to_string(f) + ")";
    if (im.size[0] < 1 || im.size[1] < 1 || im.size[2] < 1 || im.data.size() != im.num_voxels())
      throw Error(what + ": image size and voxel count disagree" + frame);
    if (!im.spacing.allFinite() || im.spacing.minCoeff() <= 0 || !im.origin.allFinite() ||
        !im.direction.allFinite() || std::abs(im.direction.determinant()) < 1e-6 ||
        !std::isfinite(im.time_s))
      throw Error(what + ": invalid geometry (spacing, origin, direction or time)" + frame);
    if (im.size != g.size || (im.spacing - g.spacing).norm() > 1e-9 ||
        (im.origin - g.origin).norm() > 1e-9 || (im.direction - g.direction).norm() > 1e-9)
      throw Error(what + ": the frames of a series must share one geometry" + frame);
  }
  switch (format) {
    case Format::kNifti:
      if (s.size() != 1) throw Error(what + ": NIfTI output is 3D only; write a series as .nrrd");
      write_nifti(path, g);
      return;
    case Format::kNrrd:
      write_nrrd_series(path, s);
      return;
    case Format::kMetaImage:
      write_metaimage_series(path, s);
      return;
  }
}

}  // namespace mvtwin
