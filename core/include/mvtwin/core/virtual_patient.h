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

  /// False with a reason in *error for impossible values.
  bool is_valid(std::string* error) const;
};

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
