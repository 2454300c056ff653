#pragma once

#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "mvtwin/core/patient.h"
#include "mvtwin/core/valve_sequence.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::forward {

/// How the marginal chordae of a valve are sized so that its simulated closure seals
/// (docs/virtual-patients.md, "Chordae tuned to the simulated closure"): each iteration
/// simulates the closure and, where a column of the closed valve is open (its gap to the other
/// leaflet above the orifice's seal), lengthens the marginal chordae of its leaflet within
/// `reach_sites` insertion sites if the other leaflet lies atrially of it (it must rise) and
/// shortens them if ventricularly, by gain x (gap - seal, at most max_step_mm) x a tent weight
/// over the sites. Every length stays within [shortest, longest] x its starting length.
struct ChordaeTuningOptions {
  ClosureOptions simulation;  ///< the model each iteration simulates (default: the paper's grid)
  int iterations = 12;        ///< length updates (iterations + 1 closures)
  double gain = 1.0;          ///< mm of length per mm of gap above the seal
  double max_step_mm = 3.0;   ///< the gap above the seal counted at most
  double reach_sites = 2.5;   ///< the tent's half-width, in insertion sites of 28
  double shortest = 0.7;      ///< x the starting length
  double longest = 1.3;       ///< x the starting length
  /// Called after each closure with its index and EROA (NaN when it failed); may be empty.
  std::function<void(int closure, double eroa_mm2)> progress;

  /// What is wrong with the options ("" when nothing).
  std::string problem() const;
};

/// What the tuning did.
struct ChordaeTuning {
  /// The lengths of the iteration whose closure had the smallest EROA (the starting lengths
  /// when no iteration improved on them).
  std::vector<ChordaLength> lengths;
  /// Per closure (0: the starting lengths), its EROA, mm^2; NaN where it failed.
  std::vector<double> eroa_mm2;
  int best = 0;  ///< index into eroa_mm2 of `lengths`
  /// The EROA of the kept lengths' closure, mm^2; NaN when the first closure failed.
  double kept_eroa_mm2() const {
    return eroa_mm2.empty() ? std::numeric_limits<double>::quiet_NaN()
                            : eroa_mm2[static_cast<size_t>(best)];
  }
  /// Why a closure failed, "" when none did.
  std::string failure;
};

/// The length changes of one iteration (mm, one per site of `lengths`) from the closed valve's
/// orifice: open columns pull or push their leaflet's chordae as ChordaeTuningOptions says.
/// `atrial` is the unit normal of the annulus plane towards the atrium.
std::vector<double> chordae_length_changes(const RegurgitantOrifice& orifice,
                                           const std::vector<ChordaLength>& lengths,
                                           const Eigen::Vector3d& atrial,
                                           const ChordaeTuningOptions& options);

/// Tunes the marginal chordae lengths of `sequence` (which must have them) for the closure with
/// `parameters`. Throws mvtwin::Error for a sequence without marginal chordae lengths or invalid
/// options; a closure that fails ends the tuning with the best lengths found before it.
ChordaeTuning tune_marginal_chordae(const ValveSequence& sequence,
                                    const ValveParameters& parameters,
                                    const ChordaeTuningOptions& options = {});

/// The tuning rule's edition: part of the key of anything made from tuned patients (the studies'
/// observed closures), so that nothing made by an older rule is read as this one's.
/// 1: lengths within 0.9-1.3 x their own (8560a4b); 2: within 0.7-1.3 (wide enough to close the
/// commissural overlaps of valves like cohort seed 7's patient 0, docs/virtual-patients.md).
inline constexpr int kChordaeTuningEdition = 2;

/// Whether `patient` is a valve that tune_normal_virtual_patient tunes: a virtual patient of the
/// normal pathology with marginal chordae lengths and no simulated closing frames.
bool is_tunable_normal_valve(const Patient& patient);

/// The chordae tuning edition recorded in a patient's anatomy (chordae_tuning_edition; 0 when
/// it was never tuned, 1 for a tuning by 8560a4b-fd0163a, which recorded no edition).
int tuning_edition(const Patient& patient);

/// Tunes a normal virtual patient's marginal chordae in place with its hidden parameters
/// (tune_marginal_chordae) and records it: chordae_tuning_iterations (the closure whose lengths
/// were kept), chordae_tuning_eroa_before_mm2 and chordae_tuning_eroa_mm2 in its anatomy (a
/// second tuning replaces the first one's) and a note in its provenance's source. Throws
/// mvtwin::Error naming the problem for a patient that is not a normal virtual one, has no
/// marginal chordae lengths, or whose closing frames were simulated (with the old chordae).
/// When the first closure fails the patient is left as it was (the result's failure says why).
ChordaeTuning tune_normal_virtual_patient(Patient* patient,
                                          const ChordaeTuningOptions& options = {});

}  // namespace mvtwin::forward
