#pragma once
#include <filesystem>
#include <vector>

#include "mvtwin/core/image_volume.h"

namespace mvtwin {

/// Reads a NIfTI-1 image (.nii or .nii.gz; either byte order; uint8/int8/int16/uint16/int32/
/// uint32/float32/float64 voxels, scaled by scl_slope/scl_inter when set). The geometry comes
/// from the sform when set, else the qform, else pixdim; mvtwin's physical space is NIfTI's
/// world space (RAS, mm). A 4D file gives one volume per time point (time from pixdim[4],
/// converted to s). Throws mvtwin::Error naming the file and the problem.
std::vector<ImageVolume> read_nifti_series(const std::filesystem::path& path);

/// Reads a 3D NIfTI image; a 4D file with more than one time point is an error.
ImageVolume read_nifti(const std::filesystem::path& path);

/// Writes a 3D float32 NIfTI-1 image (gzip-compressed when the name ends in .gz), with the
/// volume's geometry as sform and qform, atomically.
void write_nifti(const std::filesystem::path& path, const ImageVolume& image);

}  // namespace mvtwin
