#pragma once
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/outcome.h"
#include "mvtwin/core/regurgitant_orifice.h"
#include "mvtwin/core/simulation_file.h"
#include "mvtwin/core/valve_parameters.h"
#include "mvtwin/core/valve_sequence.h"
#include "mvtwin/forward/clip_device.h"
#include "mvtwin/forward/self_contact.h"
#include "mvtwin/forward/step_solver.h"
#include "mvtwin/forward/valve_model.h"

namespace mvtwin::forward {

class ClosureScene;

/// Options of a closure simulation (Mansi et al. 2012, Sec. 2.3). Units: s, t/mm^3, 1/s.
/// Times a failed clip phase is run again, each twice as long as the last (ClosureOptions::clips).
inline constexpr int kClipPhaseRetries = 2;

struct ClosureOptions {
  ModelOptions model;
  /// Time step of the simulated (stretched) time, s: the paper's step, and with error-controlled
  /// steps the smallest step the error control takes (failed steps are halved below it).
  double dt = 0.01;
  /// Error-controlled steps (StepSizeControl): steps of dt, 2 dt, ... up to max_dt while the
  /// local error estimate of a step stays below this (mm), back to dt at impacts; recorded
  /// states still fall every record_every x dt. 0 = every step is dt (the paper's scheme).
  /// Default 0.1 mm up to 0.04 s: on virtual patients 1-5 (paper's grid) 53-64 % fewer steps
  /// than fixed steps of 0.01 s, 0.009-0.084 mm (mean) from a 4x smaller fixed step, against
  /// 0.003-0.018 mm for fixed steps of 0.01 s; the closure 0.154 mm from the converged
  /// reference (0.112 up to 0.02 s, 0.106 at fixed 0.01 s). Fixed steps of 0.02 s took patient
  /// 3 2.2 mm away; the error control returns to 0.01 s where the leaflets meet
  /// (docs/forward-status.md, "Error-controlled steps as the default").
  double step_error_mm = 0.1;
  double max_dt = 0.04;   ///< the largest error-controlled step, s (dt if dt is larger)
  double stretch = 10.0;  ///< simulated closure = stretch x observed closure duration
  /// Settling: after the closure the pressure and the boundary are held at their end values and
  /// steps of dt, 2 dt, 4 dt, ... (up to settle_max_dt) run until one moves no free node by
  /// more than settle_mm: the closed valve at rest under the peak pressure, as the closed frame
  /// shows it, instead of lagging behind the load through the damping (docs/forward-status.md,
  /// "The closed valve at rest"). At 0.01 mm the end is within 0.02 mm (mean) and 0.17 mm
  /// (max) of rest on virtual patients 1-5 at the paper's grid, for 1.3-3.4x the time. 0 = off:
  /// the state when the load peaks (the paper's end state), 0.04-0.52 mm (mean) and up to 3.9 mm
  /// from rest. On a coarse 16 x 8 model, where the valve creeps, the settled end jumps with
  /// the parameters (17-22 or 65 settling steps for rest-length factors 0.01 apart); at 24 x 24
  /// and 30 x 30 it is as smooth in them as the unsettled end.
  double settle_mm = 0.01;
  /// The largest settling step, s (measured with one linearization per step: at 0.32 s the
  /// steps wandered instead of settling, docs/forward-status.md).
  double settle_max_dt = 0.08;
  double settle_max_s = 5.0;  ///< settling gives up (the valve still moving) after this, s
  /// Newton iterations per settling step at its start (up to newton_tolerance): with one,
  /// patient 4's large steps still moved 0.32 mm each after 5 s (forward-status.md).
  int settle_newton_iterations = 3;
  /// Where settling's steps flip between two states (a full-size step moves some node by more
  /// than twice what two steps together move it: the Newton iterations stop short of the step's
  /// solution, each time on the other side), the iterations per step are doubled, up to this
  /// (docs/forward-status.md, "Settling's two-step cycle"). = settle_newton_iterations: never.
  int settle_newton_max_iterations = 12;
  /// The closed valve at rest by a static solve instead of settling: after the closure (and
  /// settling to static_start_mm), Newton iterations on the static equilibrium under the held
  /// peak pressure and boundary with the exact tangent, a line search on the energy's slope that
  /// keeps every element uninverted and no node through a leaflet, and a Levenberg shift on the
  /// mass (ClosureIntegrator::solve_static). Off: settling (settle_mm).
  bool static_rest = false;
  /// Converged when the free nodes' residual force (2-norm) is below this fraction of the
  /// pressure load's (2-norm over the same nodes), or by static_step_mm.
  double static_tolerance = 1e-6;
  int static_max_iterations = 40;  ///< Newton iterations before the static solve gives up
  /// Also converged after a step along a Newton correction that moves no free node by more
  /// than this (mm), the residual below 1 % of the load (ClosureIntegrator::solve_static).
  double static_step_mm = 1e-3;
  /// Settle (as settling does) until a step moves the valve by less than this (mm) before the
  /// static solve; 0 = Newton from the closure's end. Newton from the closure's end wanders
  /// while the contact pairs change (docs/forward-status.md).
  double static_start_mm = 0.03;
  double density = 1.04e-9;         ///< t/mm^3 (1.04 g/mL)
  double rayleigh_mass = 0.1;       ///< alpha_M, 1/s
  double rayleigh_stiffness = 0.1;  ///< alpha_K, s
  /// 1 = one linearization per step (the paper's scheme); more = modified Newton iterations
  /// (the warped tangent, without the follower pressure's term: ClosureIntegrator) until the
  /// velocity update is below newton_tolerance (mm/s, infinity norm).
  int newton_iterations = 1;
  double newton_tolerance = 1e-6;
  /// The linear solver of each step (its defaults are the simulation's). The step matrix is
  /// the warped co-rotational tangent (ClosureIntegrator).
  StepSolverOptions solver;
  /// Prescribed boundary motion from the images; off = held at end-diastole (sensitivity).
  bool annulus_motion = true;
  bool papillary_motion = true;
  /// Leaflet self-contact (Mansi et al. 2012, Sec. 2.3).
  SelfContactOptions contact;
  /// Inversion guard: volumetric barrier below this det F of an element's corner tetrahedron
  /// (ElasticBody::set_inversion_guard; 0 = off).
  double inversion_guard = 0.2;
  /// Clips. With any, a clip phase of clip_closing_s (simulated) comes first: pressure off,
  /// annulus and papillary tips held at end-diastole, the clips closing smoothly from the sites'
  /// distance to their target; the closure then starts from the clipped valve.
  std::vector<ClipOptions> clips;
  double clip_closing_s = 0.5;
  /// A clip phase that fails (a grasped node driven through a leaflet while the arms close) is
  /// run again from end-diastole twice as long, at most this many times: arms closing slower
  /// end where they would have (the clipped EROA moved by at most 0.1 mm^2 over 8 options that
  /// close either way, docs/clip-devices.md), and a run that does not fail is unchanged to the
  /// bit. Not a `--set` option (it changes no result that exists without it); 0 for tests.
  int clip_phase_retries = kClipPhaseRetries;
  /// Called after every step of the closure with the simulated time and the duration (s).
  std::function<void(double t, double duration)> progress;
  /// Initial nodal velocities (3 per node of the model, mm/s; empty: at rest). Prescribed
  /// nodes start at rest whatever is given.
  Eigen::VectorXd initial_velocity;
  /// Record the atrial surface every n x dt of simulated time, i.e. every n fixed steps (0: only
  /// the end; after a halved step, at the first step on or past each of those times).
  int record_every = 0;
  /// The regurgitant orifice of the closed valve (core/regurgitant_orifice.h) is measured on the
  /// end state's atrial surface sampled this many times finer than the model grid, exactly on
  /// the elements' (curved) surface; 0 = not measured (calibration's candidates need only the
  /// surface). At 3 (columns 0.4-1.2 mm apart at the paper's grid) the AROA of virtual patients
  /// 1 and cohort seed 2026's 2 and 5 is within 1.2 % (0.12 mm^2) of 8 times finer, at 0.1-0.2 s
  /// per closure; at 2 within 3.1 %, at 4 within 0.3 % for 0.2-0.35 s
  /// (docs/regurgitant-orifice.md).
  int orifice_refine = 3;
  /// A failed step (inverted element, non-finite value, solver failure) is retried with half
  /// the step at most this many times before the simulation stops with a failure status.
  int max_step_halvings = 3;
  /// Threads of one closure: 1, or 2 to run its parallel pieces in two parts at once (the
  /// element passes, contact beside the elastic forces, the preconditioner's substitutions;
  /// docs/forward-status.md). Every piece splits its work the same way whatever this is and
  /// combines the parts in a fixed order, so results are the same bit for bit on 1 or 2.
  int threads = 2;

  bool is_valid(std::string* error) const;
};

struct ClosureSummary {
  /// How the simulation ended (kInvalidInput until it has run).
  Outcome outcome = Outcome::kInvalidInput;
  std::string reason;  ///< why it failed, naming the element, node or time; empty on success
  bool converged() const { return outcome == Outcome::kConverged; }
  int steps = 0;         ///< steps taken (after halvings)
  int halvings = 0;      ///< step retries with a halved step
  int rejected = 0;      ///< steps redone smaller because their error estimate was too large
  int crossings = 0;     ///< steps rejected by continuous collision detection (then halved)
  int settle_steps = 0;  ///< steps of the settling phase (included in steps)
  double settle_s = 0;   ///< simulated time of the settling phase, s
  /// Newton iterations per settling step at its end: settle_newton_iterations, or more where
  /// the steps flipped between two states (settle_newton_max_iterations).
  int settle_newton_iterations = 0;
  /// Largest motion of a free node over the last step, mm (at rest: below settle_mm).
  double last_step_motion_mm = 0;
  int newton_iterations = 0;
  /// The static solve (static_rest): Newton iterations, the residual force at the end (N,
  /// 2-norm over the free nodes) and as a fraction of the pressure load, its history (one entry
  /// per iteration, the start first), and its wall time (in wall_s).
  int static_iterations = 0;
  double static_residual_n = 0, static_relative_residual = 0, static_s = 0;
  double static_step_mm = 0;  ///< the last Newton correction's largest node motion, mm
  std::vector<double> static_history;
  /// Why the static solve failed (settling then brought the valve to rest), or empty.
  std::string static_failure;
  int dofs = 0, elements = 0;
  double wall_s = 0, assembly_s = 0, solve_s = 0, contact_s = 0, other_s = 0;
  int contacts = 0;          ///< vertex-triangle pairs in contact at the end
  int max_contacts = 0;      ///< most pairs at once
  int contact_searches = 0;  ///< proximity searches done
  /// Smallest signed vertex-surface distance of a contact pair at the end, mm (negative: a
  /// vertex is through a surface); infinity without contact.
  double min_contact_distance_mm = 0;
  int contact_reused = 0;        ///< detections that reused the candidate list (no search)
  double final_update_norm = 0;  ///< last velocity update, mm/s
  /// Surface nodes of one leaflet inside the other at the end (forward/interpenetration.h), of
  /// the nodes checked.
  int interpenetrating_nodes = 0, interpenetration_checked = 0;
  /// Elements compressed below the inversion guard's threshold at the last linearization.
  int guarded_elements = 0;
  int analyses = 0, factorizations = 0, pcg_iterations = 0;  ///< linear-solver work
  int preconditioner_applications = 0;
  /// Solves given earlier steps' updates as guesses (warm_start), and of those the ones the
  /// guesses answered alone (no factorization, no preconditioner application).
  int warm_starts = 0, warm_accepted = 0;
  int orderings_reused = 0;  ///< analyses that reused an ordering found earlier in the process
  int pcg_fallbacks = 0;     ///< PCG solves that gave up and factorized
  /// Single-precision factorizations redone in double (not positive definite in single).
  int double_fallbacks = 0;
  int unconverged_solves = 0;    ///< solves left above pcg_tolerance after a fresh factorization
  double factorize_s = 0;        ///< part of solve_s spent in factorizations
  double precondition_s = 0;     ///< part of solve_s spent applying the factorization
  double analyze_s = 0;          ///< part of factorize_s spent in the symbolic analysis
  double matrix_assembly_s = 0;  ///< part of assembly_s spent assembling the step matrix
  double orifice_s = 0;  ///< sampling the fine end surfaces and measuring the orifice (in other_s)
  /// The clip phase's simulated length (0 without clips): clip_closing_s, or 2 or 4 times it
  /// when it was run again after failing (clip_phase_retries times; their work is not counted
  /// above, wall_s aside).
  double clip_phase_s = 0;
  int clip_phase_retries = 0;

  std::string brief_report() const;
};

/// One recorded instant of a simulation.
struct ClosureSample {
  double time_s = 0;                                 ///< simulated time
  double observed_time_s = 0;                        ///< time on the image sequence's clock
  LeafletGrid la_surface;                            ///< atrial surface on the model grid
  double anterior_tip_mm = 0, posterior_tip_mm = 0;  ///< to the annulus plane, + atrial
  /// Regurgitant orifice (core/closure_measures.h) and the annulus opening, mm^2.
  double orifice_area_mm2 = 0, annulus_area_mm2 = 0;
  int orifice_components = 0;
  /// Smallest signed distance of a contact pair (negative: through a surface), mm.
  double min_contact_distance_mm = 0;
  /// Kinetic and elastic (leaflet) energy, N mm.
  double kinetic_energy = 0, elastic_energy = 0;
};

struct ClosureResult {
  ClosureSummary summary;
  std::vector<ClosureSample> samples;  ///< recorded states, the last is the end state
  Eigen::VectorXd positions;           ///< all nodes at the end, flattened, mm
  /// The corner (linear) mesh at rest (its nodes are the first of `positions`), and per
  /// element at the end: largest principal co-rotational strain (from the corners) and the von
  /// Mises stress of the material's response to it, MPa.
  TetMesh rest_mesh;
  Eigen::VectorXd element_strain, element_stress_mpa;
  /// Per clip: distance between its two sites' atrial surface nodes at the end of the clip
  /// phase and at the end, mm.
  std::vector<double> clip_gap_clipped_mm, clip_gap_end_mm;
  /// Elements the inversion guard held at some step (ascending): co-rotational elasticity alone
  /// would have let them collapse (the FEBio export gives them a law that cannot).
  std::vector<int> guarded_elements;
  /// Per clip: how it grasped the leaflets.
  std::vector<ClipGrasp> clip_grasps;
  /// Per chorda of the scene (ClosureScene::chordae, torn ones left out): its tension at the end,
  /// N, and whether it is marginal.
  std::vector<double> chorda_tension_n;
  std::vector<char> chorda_marginal;
  /// The closed valve's regurgitant orifice (ClosureOptions::orifice_refine; sealed where the
  /// leaflets are within the contact law's reach, orifice_seal_mm) and the fine atrial and
  /// ventricular surfaces it was measured on. Empty when not measured or when the simulation
  /// failed.
  std::optional<RegurgitantOrifice> orifice;
  LeafletGrid orifice_surface, orifice_lv_surface;
};

/// The q-quantile (q in [0, 1]) of the end state's von Mises stress over `elements` of the corner
/// mesh (ClosureResult::element_stress_mpa; linear interpolation between order statistics), kPa;
/// NaN when there are none. The 95th percentile near a grasp (ClipGrasp::region_elements) is the
/// stress measure that converges under refinement where the maximum does not (point loads at
/// chordae and ties).
double stress_quantile_kpa(const ClosureResult& result, const std::vector<int>& elements, double q);

/// The distance within which two leaflets seal: where the contact law pushes them apart
/// (SelfContactOptions: from the alarm distance in), so that they carry the pressure across.
double orifice_seal_mm(const SelfContactOptions& contact);

/// Simulates the closure of `sequence` from end-diastole to the first closed frame with the
/// given patient parameters. Never throws for a numerical failure: the summary says what
/// happened. Throws mvtwin::Error for invalid options or a sequence that cannot be modelled.
ClosureResult simulate_closure(const ValveSequence& sequence, const ValveParameters& parameters,
                               const ClosureOptions& options = {});
/// The same for a scene already built (make_closure_scene) with these options.
ClosureResult simulate_closure(const ClosureScene& scene, const ClosureOptions& options);

/// The result as a file record (core/simulation_file.h), with the options and parameters that
/// produced it.
SimulationRecord make_simulation_record(const ClosureResult& result, const ClosureOptions& options,
                                        const ValveParameters& parameters);

}  // namespace mvtwin::forward
