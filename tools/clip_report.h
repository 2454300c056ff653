#pragma once
// The clip plan as a report a clinician reads: mvtwin clip --report DIR writes DIR/report.md,
// DIR/report.html (pictures embedded) and the PNGs.
#include <filesystem>
#include <string>
#include <vector>

#include "mvtwin/core/patient.h"
#include "mvtwin/inverse/clip_prediction.h"

namespace mvtwin::tools {

struct ClipPlan {
  const Patient* patient = nullptr;
  std::string parameters_from;
  inverse::ClipScenario before;
  inverse::EverestCriteria everest;
  std::vector<inverse::ClipScenario> ranked;  ///< best first
  inverse::SigmaPoints sigma;                 ///< the intervals' points (empty: none)
  std::string intervals_why_not;              ///< when there are none
  std::string command_line;
  int jobs = 1;
  double wall_s = 0;
};

/// Writes the report and its pictures (en-face views of the valve without a clip and of the
/// best three options, closed and open; the options' EROA with their intervals). Throws
/// mvtwin::Error for an unwritable folder.
void write_clip_report(const std::filesystem::path& dir, const ClipPlan& plan);

}  // namespace mvtwin::tools
