#pragma once
#include <string>
#include <vector>

#include "mvtwin/core/patient.h"
#include "mvtwin/core/regurgitant_orifice.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::inverse {

/// A clip site on the coaptation line: position along it (0 = anterolateral commissure,
/// 1 = posteromedial) and grasp depth (1 = the free edges, smaller = deeper towards the
/// annulus). The anterior site is at s = position / 2, the posterior one opposite it at
/// s = 1 - position / 2 (forward::ClipOptions).
struct ClipSite {
  double position = 0.5;
  double depth = 1.0;
};
forward::ClipOptions clip_options(const ClipSite& site);
/// Parses "u,v[;u,v...]" (v optional, default 1). Throws mvtwin::Error naming the problem.
std::vector<ClipSite> parse_clip_sites(const std::string& text);

/// The closed valve's quality at the end of a closure simulation.
struct ClosureQuality {
  bool converged = false;
  std::string reason;
  /// The regurgitant orifice of the closed valve (ClosureResult::orifice; all zero when the
  /// simulation failed or did not measure it).
  RegurgitantOrifice orifice;
  std::vector<double> clip_gap_mm;  ///< per clip, at the end
};
ClosureQuality closure_quality(const forward::ClosureResult& r);

/// One clip scenario: the closure simulated with the clips (Mansi et al. 2012, Sec. 2.4: clipped on
/// the open valve with the pressure off, then closed under the patient's boundary motion and
/// pressure).
struct ClipScenario {
  std::vector<ClipSite> sites;
  ClosureQuality quality;
};

/// Simulates each set of sites (candidates `jobs` at a time) with the given parameters and
/// options; a failed simulation is reported in its quality, never thrown.
std::vector<ClipScenario> simulate_clips(const Patient& patient, const ValveParameters& parameters,
                                         const forward::ClosureOptions& options,
                                         const std::vector<std::vector<ClipSite>>& candidates,
                                         int jobs);

/// Candidate sites along the coaptation line at the free edges: single clips at positions
/// 0.2, 0.3, ..., 0.8, and (with pairs) every two of them at least 0.2 apart.
std::vector<std::vector<ClipSite>> clip_candidates(bool pairs);

/// Ranks scenarios: converged first, then by effective regurgitant orifice (smallest first).
void rank_by_residual_orifice(std::vector<ClipScenario>* scenarios);

}  // namespace mvtwin::inverse
