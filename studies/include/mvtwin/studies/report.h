#pragma once
// A study's report: headings, paragraphs, tables and figures, written as report.md and as a
// self-contained report.html (the PNGs embedded), so that it reads in a browser, on GitHub or
// in a terminal.
#include <filesystem>
#include <string>
#include <vector>

namespace mvtwin::studies {

class Report {
 public:
  explicit Report(std::string title) : title_(std::move(title)) {}
  void heading(const std::string& text);
  /// Markdown inline code (`x`) and bold (**x**) are rendered in HTML too.
  void paragraph(const std::string& text);
  void table(const std::vector<std::string>& header,
             const std::vector<std::vector<std::string>>& rows);
  /// A PNG beside the report (file name relative to the report's folder).
  void figure(const std::string& png, const std::string& caption);
  /// A verbatim block (commands).
  void code(const std::string& text);

  /// The closing section every study report has: the command line, the mvtwin version, where
  /// it ran and its wall time (resumed runs: this run's only).
  void how_made(const std::string& command, const std::string& workers, double wall_s);

  /// Writes DIR/report.md and DIR/report.html atomically (the PNGs must already be in DIR).
  void write(const std::filesystem::path& dir) const;

 private:
  struct Block {
    enum Kind { kHeading, kParagraph, kTable, kFigure, kCode } kind;
    std::string text, caption;
    std::vector<std::string> header;
    std::vector<std::vector<std::string>> rows;
  };
  std::string title_;
  std::vector<Block> blocks_;
};

/// "1.49 ± 0.62" style: mean ± SD with `digits` decimals; "n/a" for NaN.
std::string mean_sd(double mean, double sd, int digits = 2);
std::string number(double v, int digits = 2);

/// The paper the studies compare with, as the reports cite it.
inline constexpr const char* kPaperCitation =
    "Mansi T, Voigt I, Georgescu B, et al. An integrated framework for finite-element modeling "
    "of mitral valve biomechanics from medical images: application to MitralClip intervention "
    "planning. Medical Image Analysis 16(7):1330-1346, 2012";

}  // namespace mvtwin::studies
