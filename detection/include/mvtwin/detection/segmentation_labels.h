#pragma once
#include <string>
#include <string_view>
#include <vector>

namespace mvtwin::detection {

/// Label values of a mitral valve segmentation. A value of 0 means the structure is not
/// labelled (0 is always the background).
struct SegmentationLabels {
  int anterior = 2;
  int posterior = 3;
  int annulus = 1;    ///< 0: no annulus label (the annulus is then the leaflets' attachment rim)
  int papillary = 0;  ///< 0: no papillary-muscle label
  /// Name of the convention the values came from ("mvtool", "mvseg", "explicit", "segment
  /// names"), for the record.
  std::string convention = "mvtool";

  /// False with a reason for equal or negative values, or a missing leaflet label.
  bool is_valid(std::string* error) const;
  /// "anterior=2 posterior=3 annulus=1 (mvtool)".
  std::string describe() const;
};

/// Named conventions (docs/import.md):
///  - "mvtool": 1 annulus, 2 anterior leaflet, 3 posterior leaflet (the mvtool repository's
///    3D TEE segmentations);
///  - "mvseg": 1 posterior leaflet, 2 anterior leaflet, no annulus (MVSeg2023, the largest
///    public 3D TEE mitral dataset; also what most CT models output).
/// Throws mvtwin::Error listing the known names for an unknown one.
SegmentationLabels segmentation_labels(std::string_view convention);
std::vector<std::string> segmentation_convention_names();

/// What a segment name (3D Slicer's SegmentN_Name) stands for: "anterior", "posterior",
/// "annulus", "papillary", or "" when it names none of them. Case, spaces, '_' and '-' are
/// ignored; "anterior leaflet", "AML", "A leaflet", "mitral annulus", "papillary muscles",
/// "PPM" and the like are recognized.
std::string segment_role(std::string_view segment_name);

}  // namespace mvtwin::detection
