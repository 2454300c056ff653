#pragma once
#include <cstdint>
#include <optional>
#include <string>

#include "mvtwin/core/patient.h"

namespace mvtwin {

/// Options of the virtual patient generator.
struct VirtualPatientOptions {
  /// Grid resolution of the generated anatomy (the "image" resolution).
  int ures = 30;
  int vres = 30;
  /// Force a pathology class; drawn from the cohort mix when empty.
  std::optional<Pathology> pathology;
  /// Patient id; "virtual-<seed>" when empty.
  std::string id;
  /// Recorded as Provenance::command.
  std::string command = "mvtwin::make_virtual_patient";
  /// The closing anatomy (issue 39, docs/virtual-patients.md "Closing anatomy"), on by default:
  /// record each marginal chorda's length (taut in the estimated closed valve, never shorter than
  /// at end-diastole) as anatomy on the sequence; the hidden marginal rest-length factors are then
  /// the patient's own variation and its pathology only, and a flail is a scallop's chordae torn.
  /// False: the generator before it (rest lengths from end-diastole times group factors, 1-3 torn
  /// chordae).
  bool taut_chordae_lengths = true;
  /// > 0 closes the commissures at end-diastole as far as the leaflets beside them while the
  /// surface stays this far (mm) from itself where it folds (the facing columns, and around each
  /// commissure any two points 3/4 of a column apart along it, so that the models' elements can
  /// follow the fold); 0 leaves them hanging nearly vertically, as in early diastole (the
  /// generator before the closing anatomy).
  double commissure_clearance_mm = 1.0;
  /// Severity as the clinic sees it (edition 3, docs/virtual-patients.md): a flail's valve is
  /// myxomatous, its posterior leaflet's modulus x kFlailPosteriorModulus and its marginal
  /// chordae's stiffness x kFlailChordaeStiffness (Mills et al. 2004); false: edition 2's flails.
  bool myxomatous_flail = true;
  /// Functional MR's papillary displacement (apically 3-7 mm and apart 3-8 mm in edition 2) times
  /// this; 1: edition 2's tethering.
  double tethering_scale = 1.3;
  /// The generator before the closing anatomy (edition 1: every option above off).
  static VirtualPatientOptions before_closing_anatomy() {
    VirtualPatientOptions o = edition2();
    o.taut_chordae_lengths = false;
    o.commissure_clearance_mm = 0.0;
    return o;
  }
  /// Edition 2's generator: the closing anatomy with edition 2's severities.
  static VirtualPatientOptions edition2() {
    VirtualPatientOptions o;
    o.myxomatous_flail = false;
    o.tethering_scale = 1.0;
    return o;
  }

  /// False with a reason in *error for impossible values.
  bool is_valid(std::string* error) const;
};

/// The default generator's edition: raised whenever the default options draw different
/// patients from the same seed (2: the closing anatomy became the default; 3: myxomatous flails
/// and deeper functional-MR tethering). Caches of anything computed from default virtual
/// patients (observed closures) key on it.
inline constexpr int kVirtualPatientEdition = 3;

/// A flail valve's posterior leaflet modulus and marginal chordae stiffness, relative to the
/// patient's draw (edition 3; docs/virtual-patients.md "Severity as the clinic sees it").
inline constexpr double kFlailPosteriorModulus = 0.6;
inline constexpr double kFlailChordaeStiffness = 0.4;

/// Generates a virtual (synthetic) patient from a seed: a saddle annulus that contracts and
/// deepens from end-diastole to the first closed frame, open leaflets on the (u,v) grid,
/// papillary tips and their motion, frame times and phases, a pathology class and hidden
/// tissue parameters, all drawn from the published ranges of docs/virtual-patients.md (sources in
/// docs/virtual-patients.md). The same seed gives the same patient.
///
/// Frames up to end-diastole are geometric. The leaflets of the closing and closed frames are
/// left missing (leaflet_observed = 0, tips unobserved): they must come from a simulation with
/// a finer model than the one calibrated (issue 3), never from this geometric generator.
Patient make_virtual_patient(std::uint64_t seed, const VirtualPatientOptions& options = {});

/// The one rule by which every command draws patient `index` (from 0) of a virtual cohort:
/// its seed is splitmix64 of (cohort_seed, index), so cohorts of different seeds never share
/// patients, and its pathology is the index's turn in the Pathology list (normal, elongated
/// chordae, ruptured chordae, ...), so that any 5 consecutive patients hold every class.
struct CohortMember {
  std::uint64_t seed = 0;
  Pathology pathology = Pathology::kNormal;
  std::string id;  ///< "virtual-<cohort seed>-<index>"
};
CohortMember cohort_member(std::uint64_t cohort_seed, int index);
/// make_virtual_patient of cohort_member(cohort_seed, index) with its pathology and id.
Patient make_cohort_patient(std::uint64_t cohort_seed, int index,
                            VirtualPatientOptions options = {});

}  // namespace mvtwin
