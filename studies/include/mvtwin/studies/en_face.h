#pragma once
// The valve seen from the atrium (the surgeon's view) as a PNG: the leaflets' atrial surface
// projected along the annulus normal, the anterior leaflet at the top, the open orifice dark
// red where no leaflet covers the annulus, the clips and the regurgitant openings marked, a
// 10 mm scale bar.
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "mvtwin/core/leaflet_grid.h"

namespace mvtwin::studies {

inline constexpr unsigned char kEnFaceOpenBgr[3] = {40, 30, 150};

struct EnFaceView {
  std::string title;
  std::vector<std::string> lines;  ///< text under the title
  /// Clip positions along the coaptation line (0 = anterolateral commissure, 1 = posteromedial).
  std::vector<double> clips;
  /// Stretches of the coaptation line that leak (begin, end), marked along the free edge.
  std::vector<std::pair<double, double>> openings;
  int size_px = 560;
};

/// Writes the PNG atomically; returns its scale, pixels per mm. Throws mvtwin::Error for a
/// surface without area or an unusable path.
double write_en_face_png(const std::filesystem::path& path, const LeafletGrid& atrial_surface,
                         const EnFaceView& view);

}  // namespace mvtwin::studies
