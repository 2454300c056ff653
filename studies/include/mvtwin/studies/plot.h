#pragma once
// Plots as PNG files (OpenCV drawing): lines and markers over linear or log axes, and grouped
// bars, with a title, axis labels, ticks and a legend. Enough for the studies' figures without
// a plotting runtime.
#include <filesystem>
#include <string>
#include <vector>

namespace mvtwin::studies {

struct PlotSeries {
  std::string name;
  std::vector<double> x, y;
  bool line = true, markers = true;
  /// Error bars (same length as y) when not empty.
  std::vector<double> y_error;
};

struct Plot {
  std::string title, x_label, y_label;
  bool log_x = false, log_y = false;
  std::vector<PlotSeries> series;
  /// Horizontal reference lines (value, label), dashed.
  std::vector<std::pair<double, std::string>> h_lines;
  int width = 900, height = 560;

  /// Grouped bars instead of x/y: one group per category, one bar per series (y[i] for
  /// category i; x is ignored).
  std::vector<std::string> categories;

  /// Writes the PNG (atomically). Throws mvtwin::Error for empty plots or an unusable path.
  void write_png(const std::filesystem::path& path) const;
};

}  // namespace mvtwin::studies
