#pragma once
// 3D Slicer markups: point lists saved as .mrk.json (Slicer 4.11+) or the older .fcsv.
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace mvtwin {

struct MarkupPoint {
  std::string label;
  Eigen::Vector3d position;  ///< RAS, mm (converted from the file's LPS when it says so)
};

struct MarkupList {
  std::vector<MarkupPoint> points;
  /// The file's coordinate system as written ("LPS" or "RAS").
  std::string coordinate_system;
  /// Points skipped (position undefined or missing), by label.
  std::vector<std::string> skipped;
};

/// Reads the control points of every markups node in a .mrk.json file, or the rows of a
/// .fcsv file (the "# CoordinateSystem" header line: RAS, LPS, 0 = RAS, 1 = LPS; default LPS
/// for .mrk.json as Slicer writes it, RAS for .fcsv). Throws mvtwin::Error naming the file and
/// the problem: unreadable, malformed, a coordinate system other than RAS/LPS, non-finite
/// positions, no points.
MarkupList read_markups(const std::filesystem::path& path);

/// Writes a .mrk.json point list the way 3D Slicer does (LPS coordinates), atomically.
void write_markups_json(const std::filesystem::path& path, const std::vector<MarkupPoint>& points);

}  // namespace mvtwin
