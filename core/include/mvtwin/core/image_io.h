#pragma once
// 3D and 3D+t images in the formats of the field: NIfTI-1, NRRD and MetaImage.
//
// mvtwin's physical space is RAS in mm (NIfTI's world space, and 3D Slicer's). NRRD files say
// their space; MetaImage files are in ITK's LPS space; both are converted on reading and
// writing (x and y change sign). A series is a list of volumes of one geometry, each with its
// time in s.
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "mvtwin/core/image_volume.h"

namespace mvtwin {

/// Reads a 3D or 3D+t image by its name: .nii/.nii.gz (NIfTI-1), .nrrd/.nhdr (NRRD),
/// .mha/.mhd (MetaImage). A 3D file gives one volume. Throws mvtwin::Error naming the file and
/// the problem (unknown extension, missing or truncated data, unsupported type, ...).
std::vector<ImageVolume> read_image_series(const std::filesystem::path& path);

/// Reads a 3D image; a series of more than one volume is an error.
ImageVolume read_image(const std::filesystem::path& path);

/// Writes a series (one volume: a 3D file) atomically, format by the name: .nrrd (3D Slicer's
/// sequence layout for a series: list axis first, per-frame times in "axis 0 index values"),
/// .mha (4D MetaImage for a series, time spacing from the first two frames), .nii/.nii.gz (3D
/// only). Float voxels, compressed. Throws mvtwin::Error for an empty series, frames of
/// different geometry, non-finite geometry or an unsupported name.
void write_image_series(const std::filesystem::path& path, const std::vector<ImageVolume>& series);

/// NRRD (NRRD0001-0005): attached (.nrrd) or detached (.nhdr + "data file") data; raw, gzip or
/// ascii encoding; either endianness; 3D, or 4D with one non-spatial axis (list or time; first
/// or last) holding the frames. Spaces RAS, LPS, LAS, or none ("spacings" only).
std::vector<ImageVolume> read_nrrd_series(const std::filesystem::path& path);
/// The same, also returning the header's key/value pairs ("key:=value" lines, such as 3D
/// Slicer's SegmentN_Name of a .seg.nrrd file).
std::vector<ImageVolume> read_nrrd_series(const std::filesystem::path& path,
                                          std::map<std::string, std::string>* key_values);
void write_nrrd_series(const std::filesystem::path& path, const std::vector<ImageVolume>& series);

/// MetaImage: .mha (LOCAL data) or .mhd with a separate data file; MET_UCHAR ... MET_DOUBLE,
/// one channel; zlib-compressed or not; 3D or 4D (the 4th axis is time).
std::vector<ImageVolume> read_metaimage_series(const std::filesystem::path& path);
void write_metaimage_series(const std::filesystem::path& path,
                            const std::vector<ImageVolume>& series);

}  // namespace mvtwin
