#pragma once
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "mvtwin/core/image_volume.h"

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

/// True when NRRD header fields are those of a 3D Slicer segmentation (SegmentN_ keys).
bool is_slicer_segmentation(const std::map<std::string, std::string>& fields);

/// A 3D Slicer segmentation (.seg.nrrd) as one label map.
struct NamedSegmentation {
  /// In the mvtool values (1 annulus, 2 anterior, 3 posterior, 4 papillary muscles).
  ImageVolume label_map;
  /// Which of them the segmentation has.
  SegmentationLabels labels;
};

/// Merges the segments of a Slicer segmentation: `layers` are its volumes (one, or one per
/// layer when segments overlap), `fields` its header's SegmentN_Name / SegmentN_LabelValue /
/// SegmentN_Layer. Segments are found by name (segment_role). Throws mvtwin::Error naming
/// `source` when no anterior and posterior leaflet are named, two segments have one role, or a
/// number or layer is invalid.
NamedSegmentation slicer_segmentation(const std::vector<ImageVolume>& layers,
                                      const std::map<std::string, std::string>& fields,
                                      const std::string& source);

}  // namespace mvtwin::detection
