#pragma once
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/valve_parameters.h"
#include "mvtwin/core/valve_sequence.h"
#include "mvtwin/forward/elastic_body.h"
#include "mvtwin/forward/valve_model.h"

namespace mvtwin::forward {

/// Options of a closure simulation (SPEC Sec. 4). Units: s, t/mm^3, 1/s.
struct ClosureOptions {
  ModelOptions model;
  double dt = 0.01;                 ///< time step of the simulated (stretched) time, s
  double stretch = 10.0;            ///< simulated closure = stretch x observed closure duration
  double density = 1.04e-9;         ///< t/mm^3 (1.04 g/mL)
  double rayleigh_mass = 0.1;       ///< alpha_M, 1/s
  double rayleigh_stiffness = 0.1;  ///< alpha_K, s
  /// 1 = one linearization per step (the paper's scheme); more = Newton iterations until the
  /// velocity update is below newton_tolerance (mm/s, infinity norm).
  int newton_iterations = 1;
  double newton_tolerance = 1e-6;
  Tangent tangent = Tangent::kWarped;
  /// Prescribed boundary motion from the images; off = held at end-diastole (sensitivity).
  bool annulus_motion = true;
  bool papillary_motion = true;
  /// Marginal chordae indices (0..marginal_chordae-1) to leave out (ruptured).
  std::vector<int> ruptured_marginal_chordae;
  /// Record the atrial surface every n steps (0: only the end).
  int record_every = 0;
  /// A failed step (inverted element, non-finite value, solver failure) is retried with half
  /// the step at most this many times before the simulation stops with a failure status.
  int max_step_halvings = 3;

  bool is_valid(std::string* error) const;
};

/// How a simulation ended.
enum class ClosureStatus { kConverged, kFailed };

struct ClosureSummary {
  ClosureStatus status = ClosureStatus::kFailed;
  std::string reason;  ///< why it failed, empty on success
  int steps = 0;       ///< steps taken (after halvings)
  int halvings = 0;    ///< step retries with a halved step
  int newton_iterations = 0;
  int dofs = 0, elements = 0;
  double wall_s = 0, assembly_s = 0, solve_s = 0, contact_s = 0, other_s = 0;
  int contacts = 0;
  double final_update_norm = 0;  ///< last velocity update, mm/s

  std::string brief_report() const;
};

/// One recorded instant of a simulation.
struct ClosureSample {
  double time_s = 0;                                 ///< simulated time
  double observed_time_s = 0;                        ///< time on the image sequence's clock
  LeafletGrid la_surface;                            ///< atrial surface on the model grid
  double anterior_tip_mm = 0, posterior_tip_mm = 0;  ///< to the annulus plane, + atrial
};

struct ClosureResult {
  ClosureSummary summary;
  std::vector<ClosureSample> samples;  ///< recorded states, the last is the end state
  Eigen::VectorXd positions;           ///< all nodes at the end, flattened, mm
};

/// Simulates the closure of `sequence` from end-diastole to the first closed frame with the
/// given patient parameters. Never throws for a numerical failure: the summary says what
/// happened. Throws mvtwin::Error for invalid options or a sequence that cannot be modelled.
ClosureResult simulate_closure(const ValveSequence& sequence, const ValveParameters& parameters,
                               const ClosureOptions& options = {});

}  // namespace mvtwin::forward
