#pragma once
#include <optional>
#include <string>
#include <vector>

#include "mvtwin/core/leaflet_grid.h"
#include "mvtwin/core/patient.h"
#include "mvtwin/core/regurgitant_orifice.h"
#include "mvtwin/forward/closure_simulation.h"
#include "mvtwin/forward/diastolic_opening.h"
#include "mvtwin/inverse/outcome_uncertainty.h"

namespace mvtwin::inverse {

/// A clip on the coaptation line: position along it (0 = anterolateral commissure,
/// 1 = posteromedial) and the device (forward::clip_devices(); "spring": the paper's clip, a
/// stiff spring between one cross-section of each leaflet, then at `depth`: 1 = the free edges,
/// smaller = deeper towards the annulus). The anterior site is at s = position / 2, the
/// posterior one opposite it at s = 1 - position / 2 (forward::ClipOptions). A device grasps
/// as deep as the leaflets insert (insertion_mm > 0 overrides the geometry).
struct ClipSite {
  double position = 0.5;
  double depth = 1.0;
  std::string device = "spring";
  double insertion_mm = 0.0;
};
/// Throws mvtwin::Error for an unknown device.
forward::ClipOptions clip_options(const ClipSite& site);
/// "XTW at 0.50" (with ";" between several).
std::string describe_sites(const std::vector<ClipSite>& sites);
/// Parses "u,v[;u,v...]" (v optional, default 1), each with `device`. Throws mvtwin::Error naming
/// the problem.
std::vector<ClipSite> parse_clip_sites(const std::string& text,
                                       const std::string& device = "spring");

/// The closed valve's quality at the end of a closure simulation.
struct ClosureQuality {
  bool converged = false;
  std::string reason;
  /// The regurgitant orifice of the closed valve (ClosureResult::orifice; all zero when the
  /// simulation failed or did not measure it).
  RegurgitantOrifice orifice;
  std::vector<double> clip_gap_mm;              ///< per clip, at the end
  std::vector<forward::ClipGrasp> clip_grasps;  ///< per clip: insertion, grasped tissue
  /// End-state von Mises stress per element of the corner mesh (MPa) and chordae tensions (N).
  Eigen::VectorXd element_stress_mpa;
  std::vector<double> chorda_tension_n;
  std::vector<char> chorda_marginal;
  /// The closed valve's atrial surface at the end (for pictures).
  std::optional<LeafletGrid> closed_surface;
};

/// Stress where the clip holds the leaflets: the 95th percentile of the von Mises stress over
/// the elements near each clip's grasp (forward::ClipGrasp::region_elements), the highest of
/// the clips, kPa, on the clipped valve (`after`) and on the same elements of the valve without
/// a clip (`before`); and the largest marginal chorda tension of each, N.
struct GraspLoads {
  double stress_p95_before_kpa = 0, stress_p95_after_kpa = 0;
  double marginal_tension_before_n = 0, marginal_tension_after_n = 0;
  /// The largest element stress of the same region on the clipped valve, kPa (for comparison:
  /// it does not converge under refinement).
  double stress_max_after_kpa = 0;
};
GraspLoads grasp_loads(const ClosureQuality& without_clip, const ClosureQuality& with_clips);

/// What a clip plan warns about (docs/clip-devices.md).
struct ClipFlags {
  /// A leaflet inserts less than kMinInsertionMm into a device's arm: single-leaflet device
  /// attachment risk.
  bool detachment_risk = false;
  double min_insertion_mm = 0;  ///< the shallowest insertion of the clips (0 for the spring)
};
/// The insertion below which a grasp is flagged, mm: an mvtwin assumption (a third of the
/// 12 mm arm), not a published threshold; the insertions themselves are reported.
inline constexpr double kMinInsertionMm = 4.0;
ClipFlags clip_flags(const std::vector<forward::ClipGrasp>& grasps);

/// The EVEREST anatomic criteria for edge-to-edge repair (Feldman et al. 2009, J Am Coll Cardiol
/// 54:686; EVEREST II, Feldman et al. 2011, N Engl J Med 364:1395), on the closed valve without a
/// clip: coaptation length >= 2 mm and depth < 11 mm (functional MR), flail gap < 10 mm and
/// flail width < 15 mm (taken as the widest gap and the length of the largest opening).
struct EverestCriteria {
  double coaptation_length_mm = 0, coaptation_depth_mm = 0, flail_gap_mm = 0, flail_width_mm = 0;
  bool coaptation_length_ok = false, coaptation_depth_ok = false, flail_gap_ok = false,
       flail_width_ok = false;
  bool all_ok() const {
    return coaptation_length_ok && coaptation_depth_ok && flail_gap_ok && flail_width_ok;
  }
};
EverestCriteria everest_criteria(const RegurgitantOrifice& without_clip);
ClosureQuality closure_quality(const forward::ClosureResult& r);

/// The valve with its clips, open in diastole (forward::simulate_diastole).
struct ClipOpening {
  bool computed = false;  ///< simulated (the plan opens only its best options)
  bool converged = false;
  std::string reason;
  double mva_cm2 = 0, gradient_mmhg = 0;
  bool stenosis = false;
  std::vector<double> openings_cm2;         ///< largest first
  int frame = -1;                           ///< the open frame (forward::DiastolicOpening::frame)
  std::string fallback;                     ///< why not the widest frame (empty when it is)
  std::optional<LeafletGrid> open_surface;  ///< the open valve's atrial surface
};

/// The spread of a scenario's outcomes under the calibration's posterior (outcome_uncertainty.h).
/// Outcomes, in this order: EROA (mm^2), MVA (cm^2), mean gradient (mmHg), the grasp's stress
/// (95th percentile, kPa).
inline constexpr int kClipOutcomes = 4;
inline const char* const kClipOutcomeNames[kClipOutcomes] = {"eroa_mm2", "mva_cm2", "gradient_mmhg",
                                                             "peak_stress_kpa"};
struct ClipUncertainty {
  bool computed = false;
  /// Per outcome, sqrt(sd_parameters^2 + sd_mesh^2); NaN where a simulation failed or was not
  /// run (the mesh term only where its simulation was run and failed).
  Eigen::VectorXd sd;
  Eigen::VectorXd sd_parameters;  ///< propagated from the calibration's posterior
  /// The mesh's part: |outcome on the refined mesh - outcome on the model's| at the fitted
  /// parameters (MeshCheck); 0 when not run.
  Eigen::VectorXd sd_mesh;
  Eigen::VectorXd at_refined;  ///< outcomes on the refined mesh (NaN when not run or failed)
  Eigen::MatrixXd at_points;   ///< outcomes (columns) at each sigma point (rows)
  int failed = 0;              ///< simulations that failed at the sigma points
};

/// The discretization's part of an interval (ASME V&V 20's numerical uncertainty, estimated by
/// one refinement): every scenario simulated once more at the fitted parameters on a mesh
/// `factor` times finer in each direction (ures and vres, rounded up to even), and the change
/// taken as one SD. Measured on ten calibrated virtual patients without a clip
/// (docs/clip-devices.md, "How sure the answer is"): the truth (the fine observation model)
/// lay inside the parameters' 95 % interval for 2 of 10, with this term for 6 of 10.
struct MeshCheck {
  bool enabled = true;
  double factor = 4.0 / 3.0;  ///< the paper's 30 x 30 -> 40 x 40
};
/// The options of the refined mesh (ures and vres times `factor`, rounded up to even).
forward::ClosureOptions refined_options(const forward::ClosureOptions& options, double factor);

/// One clip scenario: the closure simulated with the clips (Mansi et al. 2012, Sec. 2.4: clipped on
/// the open valve with the pressure off, then closed under the patient's boundary motion and
/// pressure).
struct ClipScenario {
  std::vector<ClipSite> sites;
  ClosureQuality quality;
  ClipOpening opening;
  ClipUncertainty uncertainty;
};

/// The outcomes of a clipped scenario (kClipOutcomeNames; NaN where not computed); `before` is
/// the same valve without a clip (for the grasp's stress).
Eigen::VectorXd clip_outcomes(const ClipScenario& scenario, const ClosureQuality& before);

/// Fills the `uncertainty` of the first `count` scenarios: each, and the valve without a clip,
/// simulated in systole and diastole at every sigma point of the posterior (sigma_points), `jobs`
/// at a time; `before_at_center` is the valve without a clip at the fitted parameters. With
/// `mesh.enabled`, each of them also once on the refined mesh at the fitted parameters
/// (MeshCheck). Returns the sigma points (none when the posterior has no covariance: every SD 0,
/// and no mesh check). Failed simulations leave NaN, never throw.
SigmaPoints propagate_clip_uncertainty(const Patient& patient,
                                       const CalibrationPosterior& posterior,
                                       const forward::ClosureOptions& options,
                                       const forward::DiastoleOptions& diastole,
                                       const ClosureQuality& before_at_center, size_t count,
                                       int jobs, std::vector<ClipScenario>* scenarios,
                                       const MeshCheck& mesh = {});

/// Whether scenario b's EROA cannot be told from a's: their difference lies within 1.96 SD of
/// the difference (both with uncertainty from the same sigma points; the mesh's part as the
/// change of the difference on the refined mesh). False without it.
bool indistinguishable(const SigmaPoints& sp, const ClipScenario& a, const ClipScenario& b);

/// For each set of sites, the first of them that clips the valve alike: the same sites, widths,
/// spacers and stiffnesses, and the same insertions grasped (an arm caps the insertion and does
/// nothing else, so NT and XT, NTW and XTW grasp the same bands wherever the leaflets insert less
/// than 9 mm). Alike sets simulate to the same bits; simulate_clips, open_clips and the intervals
/// run each valve once.
std::vector<size_t> alike_clips(const ValveSequence& sequence,
                                const std::vector<std::vector<ClipSite>>& sites);

/// Simulates each set of sites (candidates `jobs` at a time, each valve once: alike_clips) with
/// the given parameters and options; a failed simulation is reported in its quality, never
/// thrown.
std::vector<ClipScenario> simulate_clips(const Patient& patient, const ValveParameters& parameters,
                                         const forward::ClosureOptions& options,
                                         const std::vector<std::vector<ClipSite>>& candidates,
                                         int jobs);

/// Opens the first `count` scenarios (with their clips) in diastole, `jobs` at a time; a failed
/// simulation is reported in its opening, never thrown.
void open_clips(const Patient& patient, const ValveParameters& parameters,
                const forward::ClosureOptions& options, const forward::DiastoleOptions& diastole,
                size_t count, int jobs, std::vector<ClipScenario>* scenarios);

/// Candidate sites along the coaptation line at the free edges: single clips at positions
/// 0.2, 0.3, ..., 0.8, and (with pairs) every two of them at least 0.2 apart, each with every
/// device of `devices` (both clips of a pair the same device).
std::vector<std::vector<ClipSite>> clip_candidates(bool pairs,
                                                   const std::vector<std::string>& devices = {
                                                       "spring"});
/// Pairs made from single clips: each given single with a second clip of its device at every
/// candidate position at least 0.2 away (without repeats).
std::vector<std::vector<ClipSite>> pairs_around(const std::vector<std::vector<ClipSite>>& singles);

/// Ranks scenarios: converged first, then by effective regurgitant orifice (smallest first).
void rank_by_residual_orifice(std::vector<ClipScenario>* scenarios);

}  // namespace mvtwin::inverse
