#pragma once
#include <optional>
#include <set>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/outcome.h"
#include "mvtwin/forward/closure_scene.h"
#include "mvtwin/forward/closure_simulation.h"
#include "mvtwin/forward/elastic_body.h"
#include "mvtwin/forward/self_contact.h"
#include "mvtwin/forward/step_solver.h"
#include "mvtwin/forward/symmetric_block_matrix.h"

namespace mvtwin::forward {

/// Positions (mm) and velocities (mm/s) of every node of the model, 3 per node, flattened.
struct ValveState {
  Eigen::VectorXd x, v;
};

/// How one step (or one linearization) ended; `message` names the element, node or solver.
struct StepOutcome {
  Outcome outcome = Outcome::kConverged;
  std::string message;
  bool ok() const { return outcome == Outcome::kConverged; }
};

/// The time integrator of a closure scene: the forces on the valve, the linear system of an
/// implicit Euler step, a trial step with its checks, and the measurements recorded along the
/// way. simulate_closure() is a driver over it (the step size, halvings, the clip phase, what to
/// record); tests use it to check the step system on its own.
///
/// One step from (x0, v0) at tau to tau + h solves for the end velocity v1 the residual
///   r(v1) = M (v1 - v0) - h f(x0 + h v1, v1)
/// over the free (not prescribed) degrees of freedom, where f holds the elastic forces, Rayleigh
/// damping (alpha_M M v + alpha_K K v), the chordae and clip springs, leaflet contact with
/// friction and the ventricular pressure. Each linearization solves A dv = -r with
///   A = (1 + h alpha_M) M + (h alpha_K + h^2) K + h^2 (K_cables + K_contact) + h C_contact
/// in which K is the warped co-rotational stiffness R K0 R^T (the paper's, SOFA's), without the
/// derivative of the rotations; the follower pressure's tangent is left out (it is not
/// symmetric, and A must be for the Cholesky-preconditioned conjugate gradients); so is the
/// derivative of alpha_K K with respect to the positions. options.newton_iterations > 1 thus
/// iterates a modified Newton method: it converges to the implicit Euler step, linearly rather
/// than quadratically. One linearization per step (the default) is the paper's semi-implicit
/// scheme.
class ClosureIntegrator {
 public:
  /// `scene` must outlive the integrator. Throws mvtwin::Error for invalid options.
  ClosureIntegrator(const ClosureScene& scene, const ClosureOptions& options);
  ClosureIntegrator(const ClosureIntegrator&) = delete;
  ClosureIntegrator& operator=(const ClosureIntegrator&) = delete;

  const ClosureScene& scene() const { return scene_; }
  int num_dofs() const { return ndof_; }
  /// The degrees of freedom that are solved for, in the order of the step system's rows.
  const std::vector<int>& free_dofs() const { return free_dofs_; }
  /// Length of the clip phase (simulated time before 0), s; 0 without clips.
  double clip_phase_s() const { return clip_phase_; }

  /// The model at rest with options.initial_velocity (prescribed nodes at rest). Throws
  /// mvtwin::Error for an initial velocity of the wrong size or with non-finite values.
  ValveState initial_state() const;

  /// One implicit Euler step from `state` at tau to tau + h: options.newton_iterations
  /// linearizations, then the checks of the trial step (finite, no inverted element, no node
  /// through a leaflet surface). On failure `state` is left unchanged.
  StepOutcome step(double tau, double h, ValveState* state);
  /// The static equilibrium at simulated time tau (the pressure and the prescribed nodes held
  /// where they are at tau; contact without friction) from state->x, by Newton's method
  /// (ClosureOptions::static_rest): each iteration solves (K + mu M) dx = -r, K the tangent of
  /// every force (the consistent co-rotational tangent with the rotations' derivative and the
  /// inversion guard, chordae and clips, the follower pressure, contact's exact stiffness; not
  /// symmetric), by GMRES preconditioned by a Cholesky factorization of its symmetric positive
  /// definite part (the warped tangent, reused while it serves), to a tolerance that tightens
  /// with the residual; then a line search on the energy's slope along dx, r(x + s dx) . dx,
  /// whose every trial keeps the elements uninverted and no node through a leaflet. mu (a
  /// Levenberg shift on the mass) relaxes after full steps and grows after short ones or when dx
  /// does not descend. Converged when |r| <= static_tolerance |pressure load| (2-norms over the
  /// free dofs), or when a Newton correction moves no node by more than static_step_mm with
  /// |r| <= kStaticStepResidual |pressure load| (contact's facet normals switch, which leaves a
  /// residual that no small step lowers: docs/forward-status.md); given up after
  /// static_max_iterations, or earlier when Newton stalls (static_stalled). A line-search trial
  /// that raises |r| by more than kStaticResidualGrowth is refused whatever its slope. On success
  /// state->x is the rest state and state->v zero; on failure the state is left as it was given (an
  /// unconverged iterate may lie farther from rest than its start even at a lower residual:
  /// settling goes on from the start, as it would have without the static solve). The residual
  /// history, the iterations and the time are in counters().
  StepOutcome solve_static(double tau, ValveState* state);
  static constexpr int kStaticLineSearch = 6;
  /// The residual (fraction of the pressure load) below which a small full step converges.
  static constexpr double kStaticStepResidual = 1e-2;
  /// The most a line-search trial may raise |r| and still pass the slope's test. Along a right
  /// step |r| may rise some (the stiff in-plane dofs); on bench closure's virtual patient 3 the
  /// slope's test took a trial that raised it 128-fold, and Newton never recovered.
  static constexpr double kStaticResidualGrowth = 10.0;
  /// Newton has stalled when its lowest residual so far has not halved over the last
  /// kStaticStallIterations iterations (history: |r| at the start and after each iteration).
  static constexpr int kStaticStallIterations = 8;
  static bool static_stalled(std::span<const double> history);
  /// Forces (N, all dofs) of the static problem at positions x and time tau: minus the elastic
  /// gradient, chordae and clips, contact without friction and the pressure (whose part alone
  /// goes to *pressure when not null); keeps each term's linearization for the static tangent.
  StepOutcome static_forces(const Eigen::VectorXd& x, double tau, Eigen::VectorXd* f,
                            Eigen::VectorXd* pressure = nullptr);
  /// Linearizes the static tangent (K + shift M) at x after static_forces() at x (its
  /// preconditioner's matrix into the step matrix); then y = (K + shift M) p over the free dofs
  /// with every coupling, for tests against finite differences of static_forces().
  StepOutcome assemble_static(const Eigen::VectorXd& x, double tau, double shift);
  void multiply_static(const Eigen::VectorXd& p, Eigen::VectorXd* y);

  /// The local error estimate of a step from `before` to `after` of size h: h/2 times the
  /// largest change of a free node's velocity, mm (StepSizeControl).
  double local_error(const ValveState& before, const ValveState& after, double h) const;
  /// Turns contact friction off (the settling phase: the regularized friction vanishes at rest
  /// anyway, only far more slowly).
  void disable_friction() {
    if (contact_) contact_->set_friction(0.0);
  }
  /// Newton iterations per step from now on (the settling phase's own count).
  void set_newton_iterations(int n) { options_.newton_iterations = n; }
  /// Newton iterations also stop once a correction moves no free node by more than this over
  /// the step (h times the velocity update, mm; 0 = only newton_tolerance).
  void set_newton_motion_tolerance(double mm) { newton_motion_tolerance_mm_ = mm; }
  /// The largest distance a free node moved between two states, mm.
  double largest_motion(const ValveState& before, const ValveState& after) const;

  // The step system, for tests and diagnostics.

  /// The first guess of a step's end velocity: v0 on free nodes, the prescribed nodes' motion
  /// over the step on the others.
  Eigen::VectorXd first_guess(const ValveState& start, double tau, double h) const;
  /// Linearizes the step from `start` at tau to tau + h at end velocity v1 (all dofs): forces,
  /// rotations, spring tangents, contact pairs, and the residual r(v1).
  StepOutcome linearize(const ValveState& start, double tau, double h, const Eigen::VectorXd& v1);
  /// r(v1) over the free dofs at the last linearization.
  const Eigen::VectorXd& residual() const { return residual_; }
  /// y = A p over the free dofs at the last linearization (every coupling, contact included).
  void multiply(const Eigen::VectorXd& p, Eigen::VectorXd* y);

  /// The force terms in the residual and the step matrix. All are on in a simulation; a test
  /// switches some off to check each term's tangent against finite differences of its force.
  /// Inertia and Rayleigh mass damping are always on.
  struct Terms {
    bool elastic = true;   ///< elastic forces, stiffness-proportional damping
    bool springs = true;   ///< chordae and clips
    bool contact = true;   ///< leaflet contact and friction (when options.contact)
    bool pressure = true;  ///< the ventricular pressure
  };
  void set_terms(const Terms& terms) { terms_ = terms; }

  /// The measurements of one recorded instant (simulated time tau).
  ClosureSample sample(double tau, const ValveState& state) const;
  /// The atrial (first) and ventricular (second) surfaces of `state` on a grid `refine` times
  /// finer than the model grid (ures x refine columns, (vres - 1) x refine + 1 rows), sampled on
  /// the elements' surfaces.
  std::pair<LeafletGrid, LeafletGrid> leaflet_surfaces(const ValveState& state, int refine) const;
  /// Per element of the corner mesh at positions x: the largest principal co-rotational strain
  /// and the von Mises stress of the scene's leaflet material's response to it, MPa.
  void strain_and_stress(const Eigen::VectorXd& x, Eigen::VectorXd* strain,
                         Eigen::VectorXd* stress_mpa) const;
  /// Distance between the two sites of clip c (0-based) at positions x, mm.
  double clip_gap(int c, const Eigen::VectorXd& x) const;
  int num_clips() const { return static_cast<int>(scene_.grasps.size()); }
  const std::vector<ClipGrasp>& grasps() const { return scene_.grasps; }
  /// Where a node of the model is, for messages: " (anterior leaflet, s = 0.230, 85 % of the way
  /// to the free edge, atrial surface, grasped by clip 1)"; empty without a model.
  std::string describe_node(int node) const;

  /// Work counters so far (steps and halvings are the driver's): crossings, Newton iterations,
  /// time per part, contact and linear-solver statistics. Interpenetration is measured by
  /// finish().
  const ClosureSummary& counters() const { return counters_; }
  /// Replaces `result`'s summary by the counters with its end positions' interpenetration (the
  /// driver sets the outcome, steps and halvings afterwards), and fills the rest mesh and the
  /// end strain and stress.
  void finish(ClosureResult* result) const;

 private:
  // A two-point force element: a chorda (to a papillary tip) or a clip spring (between two
  // cross-sections); each end is the mean of a node set or a prescribed point.
  struct Cable {
    std::vector<int> a, b;  // node sets; b empty: the far end is papillary tip `tip`
    int tip = -1;
    double rest = 0.0;
    const ChordaLaw* law = nullptr;  // null: linear spring of stiffness k
    double k = 0.0;
    bool bilateral = false;  // a linear spring that pushes as well as pulls
    int clip = -1;           // the clip of a spring
  };
  double cable_rest(size_t c, double tau) const;
  int force_pass(const Eigen::VectorXd& x, const Eigen::VectorXd& v, const Eigen::VectorXd* p,
                 Eigen::VectorXd* g, Eigen::VectorXd* Kp, Eigen::VectorXd* fc, double* contact_s);
  void add_cable_forces(const Eigen::VectorXd& x, double tau, Eigen::VectorXd* f);
  void add_pressure_forces(const Eigen::VectorXd& x, double tau, Eigen::VectorXd* f) const;
  /// y += s K_cables p (all dofs) at the last linearization.
  void add_cable_products(const Eigen::VectorXd& p, double s, Eigen::VectorXd* y) const;
  /// y += K_pressure p (all dofs): the follower pressure's tangent at the last assemble_static().
  void add_pressure_products(const Eigen::VectorXd& p, Eigen::VectorXd* y) const;
  void add_cable_cliques(double s);  ///< the cables' tangents, times s, into the step matrix
  Eigen::Vector3d mean_of(const std::vector<int>& nodes, const Eigen::VectorXd& at) const;
  const Eigen::SparseMatrix<double>& assemble_lower();
  void rotate(Eigen::VectorXd* v, bool transpose);
  void update_node_rotation();
  StepOutcome check_trial(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1);

  const ClosureScene& scene_;
  ClosureOptions options_;
  double newton_motion_tolerance_mm_ = 0.0;
  Terms terms_;
  ElasticBody body_;
  int n_ = 0, ndof_ = 0;
  std::vector<Cable> cables_;
  int first_spring_ = 0;
  std::vector<char> fixed_;
  std::vector<int> free_dofs_;
  Eigen::VectorXd rest_, mass_, mass_dof_;
  std::optional<SelfContact> contact_;
  AtrialSampler sampler_;
  std::optional<SymmetricBlockMatrix> system_;
  int first_cable_clique_ = 0;
  StepSolver linear_;
  /// The first Newton updates of the last solved steps (most recent first) and their step
  /// sizes: scaled by the step ratio, the next step's guesses for its update
  /// (StepSolverOptions::warm_start).
  static constexpr size_t kWarmUpdates = 2;
  std::vector<std::pair<Eigen::VectorXd, double>> last_updates_;
  double clip_phase_ = 0.0;
  std::vector<double> spring_start_;

  // The last linearization.
  double h_ = 0.0, ck_ = 0.0, cm_ = 0.0;
  ElementRotations rot_, rot_at_factor_;
  std::set<int> ever_guarded_;  ///< elements the inversion guard held at some linearization
  std::vector<Eigen::Matrix3d> cable_tangent_;
  // Rotation of each node's neighbourhood since the last factorization (the rotated
  // preconditioner, StepSolver::System::rotate), computed when first needed.
  std::vector<Eigen::Matrix3d> node_rotation_;
  bool node_rotation_current_ = false;
  Eigen::VectorXd residual_, p_all_, y_all_;

  // The static solve's tangent at the last assemble_static(): each element's consistent
  // tangent, the positions and pressure of the follower load's, the shift; its linear solver.
  std::vector<Eigen::MatrixXd> static_k_;
  Eigen::VectorXd static_x_;
  double static_pressure_ = 0.0, static_shift_ = 0.0;
  std::optional<StepSolver> static_linear_;

  ClosureSummary counters_;
};

}  // namespace mvtwin::forward
