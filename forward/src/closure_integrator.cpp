#include "mvtwin/forward/closure_integrator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include "mvtwin/core/annulus_plane.h"
#include "mvtwin/core/closure_measures.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/stopwatch.h"
#include "mvtwin/forward/chorda.h"
#include "mvtwin/forward/interpenetration.h"
#include "run_both.h"

namespace mvtwin::forward {
namespace {

using Clock = std::chrono::steady_clock;

StepOutcome failed(Outcome o, std::string message) { return {o, std::move(message)}; }

}  // namespace

ClosureIntegrator::ClosureIntegrator(const ClosureScene& scene, const ClosureOptions& options)
    : scene_(scene),
      options_(options),
      body_(scene.model.mesh,
            [&scene](int tag) {
              return scene.leaflet_material[tag == static_cast<int>(LeafletTag::kAnterior) ? 0 : 1];
            }),
      linear_(options.solver) {
  std::string why;
  if (!options_.is_valid(&why)) throw Error("closure options: " + why);
  const SolidMesh& mesh = scene_.model.mesh;
  body_.set_inversion_guard(options_.inversion_guard);
  linear_.set_threads(options_.threads);
  body_.set_threads(options_.threads);
  n_ = mesh.num_nodes();
  ndof_ = 3 * n_;

  for (const SceneChorda& c : scene_.chordae)
    cables_.push_back({c.nodes, {}, c.tip, c.rest_length, &c.law, 0.0});
  first_spring_ = static_cast<int>(cables_.size());
  for (const SceneSpring& sp : scene_.springs)
    cables_.push_back(
        {sp.a, sp.b, -1, sp.rest_length, nullptr, sp.stiffness, sp.bilateral, sp.clip});
  cable_tangent_.resize(cables_.size());

  fixed_.assign(ndof_, 0);
  std::vector<char> node_free(n_, 1);
  for (const PrescribedNode& pr : scene_.prescribed) {
    fixed_[3 * pr.node] = fixed_[3 * pr.node + 1] = fixed_[3 * pr.node + 2] = 1;
    node_free[pr.node] = 0;
  }
  for (int i = 0; i < ndof_; ++i) {
    if (!fixed_[i]) free_dofs_.push_back(i);
  }
  rest_ = body_.rest_positions();
  mass_ = body_.lumped_mass(options_.density);
  mass_dof_.resize(ndof_);
  for (int i = 0; i < ndof_; ++i) mass_dof_[i] = mass_[i / 3];
  counters_.dofs = static_cast<int>(free_dofs_.size());
  counters_.elements = mesh.num_elements();

  if (options_.contact.enabled) {
    const double thinnest =
        std::min(options_.model.al_thickness_mm, options_.model.pl_thickness_mm);
    contact_.emplace(SelfContact::valve_surface(scene_.model), options_.contact,
                     options_.contact.stiffness_per_area(scene_.peak_pressure_mpa), 0.5 * thinnest);
    contact_->set_threads(options_.threads);
  }
  sampler_ = make_atrial_sampler(scene_.model, options_.model.ures, options_.model.vres);

  // The step matrix on a fixed pattern: every element, and each cable's end nodes.
  std::vector<std::vector<int>> cliques = body_.element_cliques();
  first_cable_clique_ = static_cast<int>(cliques.size());
  for (const Cable& cb : cables_) {
    std::vector<int> c = cb.a;
    c.insert(c.end(), cb.b.begin(), cb.b.end());
    cliques.push_back(c);
  }
  system_.emplace(node_free, cliques);
  if (system_->rows() != static_cast<int>(free_dofs_.size()))
    throw Error("closure simulation: internal error (free dofs and system rows differ)");
  node_rotation_.resize(n_);
  p_all_ = Eigen::VectorXd::Zero(ndof_);
  y_all_.resize(ndof_);

  // Clip phase (Mansi et al. 2012, Sec. 2.4), simulated time [-clip_closing_s, 0): pressure
  // off, annulus and papillary tips held at end-diastole, each clip's rest length closing
  // smoothly from the sites' distance at rest to its target.
  clip_phase_ = scene_.springs.empty() ? 0.0 : options_.clip_closing_s;
  spring_start_.assign(cables_.size(), 0.0);
  for (size_t c = first_spring_; c < cables_.size(); ++c)
    spring_start_[c] = (mean_of(cables_[c].a, rest_) - mean_of(cables_[c].b, rest_)).norm();
}

Eigen::Vector3d ClosureIntegrator::mean_of(const std::vector<int>& nodes,
                                           const Eigen::VectorXd& at) const {
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  for (int k : nodes) m += at.segment<3>(3 * k);
  return m / static_cast<double>(nodes.size());
}

double ClosureIntegrator::cable_rest(size_t c, double tau) const {
  if (static_cast<int>(c) < first_spring_ || tau >= 0.0) return cables_[c].rest;
  const double q = 1.0 - std::min(1.0, -tau / clip_phase_);  // 0 at the phase's start
  const double w = q * q * (3.0 - 2.0 * q);
  const double closing = (1.0 - w) * spring_start_[c] + w * cables_[c].rest;
  // A tension-only clip never pushes the sites apart; a device's tie takes them to its length.
  return cables_[c].bilateral ? closing : std::max(cables_[c].rest, closing);
}

ValveState ClosureIntegrator::initial_state() const {
  ValveState s{rest_, Eigen::VectorXd::Zero(ndof_)};
  if (options_.initial_velocity.size() > 0) {
    if (options_.initial_velocity.size() != ndof_ || !options_.initial_velocity.allFinite()) {
      throw Error("closure options: initial_velocity needs " + std::to_string(ndof_) +
                  " finite values (3 per node)");
    }
    s.v = options_.initial_velocity;
    for (int i = 0; i < ndof_; ++i) {
      if (fixed_[i]) s.v[i] = 0.0;
    }
  }
  return s;
}

Eigen::VectorXd ClosureIntegrator::first_guess(const ValveState& start, double tau,
                                               double h) const {
  const double scene_time = std::max(tau + h, 0.0);  // the clip phase holds end-diastole
  Eigen::VectorXd xp1 = start.x;
  scene_.prescribed_positions(scene_time, &xp1);
  Eigen::VectorXd v1 = start.v;
  for (const PrescribedNode& pr : scene_.prescribed)
    v1.segment<3>(3 * pr.node) = (xp1 - start.x).segment<3>(3 * pr.node) / h;
  return v1;
}

// Elastic forces (and K p with p) in one pass, and beside it (run_both) the contact's search and
// forces (velocities v for friction) into their own vector. Returns the first inverted element
// or -1; *contact_s: the contact's time.
int ClosureIntegrator::force_pass(const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                                  const Eigen::VectorXd* p, Eigen::VectorXd* g, Eigen::VectorXd* Kp,
                                  Eigen::VectorXd* fc, double* contact_s) {
  int bad = -1;
  run_both(
      options_.threads,
      [&] {
        if (!terms_.elastic) return;
        bad = body_.gradient(x, g, &rot_, nullptr, p, Kp);
        node_rotation_current_ = false;
        for (const ElementRotations::Guard& gd : rot_.guards) ever_guarded_.insert(gd.element);
      },
      [&] {
        if (!(contact_ && terms_.contact)) return;
        const auto tc = Clock::now();
        const int found = contact_->detect(x);
        counters_.contacts = found;
        counters_.max_contacts = std::max(counters_.max_contacts, found);
        fc->setZero(ndof_);
        contact_->add_forces(v, fc);
        *contact_s = seconds_since(tc);
      });
  return bad;
}

StepOutcome ClosureIntegrator::linearize(const ValveState& start, double tau, double h,
                                         const Eigen::VectorXd& v1) {
  const auto ta = Clock::now();
  const double tau1 = tau + h;
  h_ = h;
  ck_ = h * options_.rayleigh_stiffness + h * h;  // K's factor in the step matrix
  cm_ = 1.0 + h * options_.rayleigh_mass;         // M's factor
  const Eigen::VectorXd x1 = start.x + h * v1;

  // Elastic forces and K v1 (for the stiffness-proportional damping) in one pass, and beside
  // it (run_both) the contact's search and forces into their own vector.
  Eigen::VectorXd f = -options_.rayleigh_mass * mass_dof_.cwiseProduct(v1);
  Eigen::VectorXd g, Kv, fc;
  double contact_s = 0.0;
  const bool with_contact = contact_ && terms_.contact;
  const int bad = force_pass(x1, v1, &v1, &g, &Kv, &fc, &contact_s);
  counters_.contact_s += contact_s;
  if (bad >= 0) {
    counters_.assembly_s += seconds_since(ta) - contact_s;
    return failed(Outcome::kInvertedElement, "element " + std::to_string(bad) + " inverted");
  }
  if (terms_.elastic)
    f = -g - options_.rayleigh_mass * mass_dof_.cwiseProduct(v1) - options_.rayleigh_stiffness * Kv;
  if (terms_.springs) add_cable_forces(x1, tau1, &f);
  if (with_contact) f += fc;
  if (terms_.pressure) add_pressure_forces(x1, tau1, &f);
  residual_.resize(static_cast<Eigen::Index>(free_dofs_.size()));
  for (size_t i = 0; i < free_dofs_.size(); ++i) {
    const int d = free_dofs_[i];
    residual_[static_cast<Eigen::Index>(i)] = mass_[d / 3] * (v1[d] - start.v[d]) - h * f[d];
  }
  // With two threads the contact ran beside the elastic pass: count only the rest here.
  counters_.assembly_s += seconds_since(ta) - contact_s;
  return {};
}

void ClosureIntegrator::add_cable_forces(const Eigen::VectorXd& x, double tau, Eigen::VectorXd* f) {
  const double scene_time = std::max(tau, 0.0);
  const Eigen::Vector3d tips[2] = {scene_.papillary_tip(0, scene_time),
                                   scene_.papillary_tip(1, scene_time)};
  for (size_t c = 0; c < cables_.size(); ++c) {
    const Cable& cb = cables_[c];
    Eigen::Matrix<double, 6, 1> gc;
    Eigen::Matrix<double, 6, 6> Hc;
    const double rest = cable_rest(c, tau);
    const Eigen::Vector3d end = cb.b.empty() ? tips[cb.tip] : mean_of(cb.b, x);
    if (cb.bilateral) {
      tie_gradient(cb.k, rest, mean_of(cb.a, x), end, &gc, &Hc);
    } else {
      // A clip is a tension-only linear spring: force k (l - L0) as a law in strain.
      const ChordaLaw law = cb.law ? *cb.law : ChordaLaw{1.0, cb.k * rest, cb.k * rest, 1.0};
      chorda_gradient(law, rest, mean_of(cb.a, x), end, &gc, &Hc);
    }
    for (int k : cb.a) f->segment<3>(3 * k) -= gc.head<3>() / static_cast<double>(cb.a.size());
    for (int k : cb.b) f->segment<3>(3 * k) -= gc.tail<3>() / static_cast<double>(cb.b.size());
    cable_tangent_[c] = Hc.topLeftCorner<3, 3>();
  }
}

void ClosureIntegrator::add_pressure_forces(const Eigen::VectorXd& x, double tau,
                                            Eigen::VectorXd* f) const {
  const double p = tau < 0.0 ? 0.0 : scene_.pressure(tau);
  for (const PressureFace& pf : scene_.pressure_faces) {
    const Eigen::Vector3d a = x.segment<3>(3 * pf.a), b = x.segment<3>(3 * pf.b),
                          c = x.segment<3>(3 * pf.c);
    const Eigen::Vector3d force = -p * 0.5 * (b - a).cross(c - a) / 3.0;
    for (int k = 0; k < 3; ++k) f->segment<3>(3 * pf.load[k]) += force;
  }
}

void ClosureIntegrator::add_cable_products(const Eigen::VectorXd& p, double s,
                                           Eigen::VectorXd* y) const {
  for (size_t c = 0; c < cables_.size(); ++c) {
    const Cable& cb = cables_[c];
    Eigen::Vector3d d = mean_of(cb.a, p);
    if (!cb.b.empty()) d -= mean_of(cb.b, p);
    const Eigen::Vector3d t = s * (cable_tangent_[c] * d);
    for (int k : cb.a) y->segment<3>(3 * k) += t / static_cast<double>(cb.a.size());
    for (int k : cb.b) y->segment<3>(3 * k) -= t / static_cast<double>(cb.b.size());
  }
}

void ClosureIntegrator::multiply(const Eigen::VectorXd& pf, Eigen::VectorXd* y) {
  const double h = h_;
  for (size_t i = 0; i < free_dofs_.size(); ++i)
    p_all_[free_dofs_[i]] = pf[static_cast<Eigen::Index>(i)];
  y_all_.setZero();
  if (terms_.elastic) {
    body_.tangent_times(rot_, p_all_, &y_all_);
    y_all_ *= ck_;
  }
  if (terms_.springs) add_cable_products(p_all_, h * h, &y_all_);
  if (contact_ && terms_.contact) contact_->multiply(p_all_, h * h, h, &y_all_);
  y->resize(pf.size());
  for (size_t i = 0; i < free_dofs_.size(); ++i) {
    const int d = free_dofs_[i];
    (*y)[static_cast<Eigen::Index>(i)] = y_all_[d] + cm_ * mass_dof_[d] * p_all_[d];
  }
}

void ClosureIntegrator::add_cable_cliques(double s) {
  for (size_t c = 0; c < cables_.size(); ++c) {
    const Cable& cb = cables_[c];
    const int ma = static_cast<int>(cb.a.size()), m = ma + static_cast<int>(cb.b.size());
    Eigen::MatrixXd K(3 * m, 3 * m);
    for (int i = 0; i < m; ++i) {
      const double wi = i < ma ? 1.0 / ma : -1.0 / (m - ma);
      for (int j = 0; j < m; ++j) {
        const double wj = j < ma ? 1.0 / ma : -1.0 / (m - ma);
        K.block<3, 3>(3 * i, 3 * j) = wi * wj * cable_tangent_[c];
      }
    }
    system_->add_clique(first_cable_clique_ + static_cast<int>(c), K, s);
  }
}

// The factorized matrix: A without the contact couplings (their diagonal blocks only),
// assembled only when the solver factorizes.
const Eigen::SparseMatrix<double>& ClosureIntegrator::assemble_lower() {
  const auto t0 = Clock::now();
  const double h = h_;
  SymmetricBlockMatrix& system = *system_;
  system.set_zero();
  if (terms_.elastic) body_.assemble_tangent(rot_, ck_, &system);
  if (terms_.springs) add_cable_cliques(h * h);
  if (contact_ && terms_.contact) contact_->add_diagonal_blocks(h * h, h, &system);
  system.add_diagonal(cm_ * mass_);
  rot_at_factor_ = rot_;
  node_rotation_current_ = false;
  counters_.matrix_assembly_s += seconds_since(t0);
  return system.lower();
}

void ClosureIntegrator::update_node_rotation() {
  const SolidMesh& mesh = scene_.model.mesh;
  for (auto& Q : node_rotation_) Q.setZero();
  const int npe = mesh.nodes_per_element();
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const Eigen::Matrix3d D = rot_.R[e] * rot_at_factor_.R[e].transpose();
    for (int a = 0; a < npe; ++a) node_rotation_[mesh.T(e, a)] += D;
  }
  for (auto& Q : node_rotation_) {
    Eigen::Matrix3d R, S;
    Q = polar_decomposition(Q, &R, &S) ? R : Eigen::Matrix3d::Identity();
  }
  node_rotation_current_ = true;
}

void ClosureIntegrator::rotate(Eigen::VectorXd* vf, bool transpose) {
  if (!node_rotation_current_) update_node_rotation();
  for (int i = 0; i < n_; ++i) {
    const int f0 = system_->first_row(i);
    if (f0 < 0) continue;
    const Eigen::Vector3d a = vf->segment<3>(f0);
    vf->segment<3>(f0) = transpose ? Eigen::Vector3d(node_rotation_[i].transpose() * a)
                                   : Eigen::Vector3d(node_rotation_[i] * a);
  }
}

StepOutcome ClosureIntegrator::step(double tau, double h, ValveState* state) {
  Eigen::VectorXd v1 = first_guess(*state, tau, h);
  StepSolver::System A{[this](const Eigen::VectorXd& p, Eigen::VectorXd* y) { multiply(p, y); },
                       [this]() -> const Eigen::SparseMatrix<double>& { return assemble_lower(); },
                       nullptr};
  if (terms_.elastic)
    A.rotate = [this](Eigen::VectorXd* v, bool transpose) { rotate(v, transpose); };

  for (int it = 0; it < options_.newton_iterations; ++it) {
    if (StepOutcome o = linearize(*state, tau, h, v1); !o.ok()) return o;
    const auto ts = Clock::now();
    const double matrix_before = counters_.matrix_assembly_s;
    // Under a smoothly varying load the update (h times the acceleration) changes little from
    // one step to the next: the last two, scaled to this step, are the solver's guesses.
    std::vector<Eigen::VectorXd> guesses;
    if (it == 0 && options_.solver.warm_start)
      for (const auto& [u, hu] : last_updates_) guesses.push_back(u * (h / hu));
    A.guesses = guesses.empty() ? nullptr : &guesses;
    Eigen::VectorXd dv;
    std::string why;
    const bool solved = linear_.solve(A, -residual_, &dv, &why);
    const double matrix_s = counters_.matrix_assembly_s - matrix_before;
    counters_.solve_s += seconds_since(ts) - matrix_s;
    counters_.assembly_s += matrix_s;
    if (!solved) return failed(Outcome::kLinearSolver, why);
    if (it == 0 && options_.solver.warm_start) {
      if (last_updates_.size() == kWarmUpdates) last_updates_.pop_back();
      last_updates_.insert(last_updates_.begin(), {dv, h});
    }
    for (size_t i = 0; i < free_dofs_.size(); ++i)
      v1[free_dofs_[i]] += dv[static_cast<Eigen::Index>(i)];
    ++counters_.newton_iterations;
    counters_.final_update_norm = dv.lpNorm<Eigen::Infinity>();
    if (counters_.final_update_norm < options_.newton_tolerance ||
        h * counters_.final_update_norm < newton_motion_tolerance_mm_)
      break;
  }
  const Eigen::VectorXd x1 = state->x + h * v1;
  if (StepOutcome o = check_trial(state->x, x1); !o.ok()) return o;
  state->x = x1;
  state->v = v1;
  return {};
}

double ClosureIntegrator::local_error(const ValveState& before, const ValveState& after,
                                      double h) const {
  double dv = 0.0;
  for (int i = 0; i < n_; ++i) {
    if (fixed_[3 * i]) continue;
    dv = std::max(dv, (after.v.segment<3>(3 * i) - before.v.segment<3>(3 * i)).norm());
  }
  return 0.5 * h * dv;
}

double ClosureIntegrator::largest_motion(const ValveState& before, const ValveState& after) const {
  double d = 0.0;
  for (int i = 0; i < n_; ++i) {
    if (fixed_[3 * i]) continue;
    d = std::max(d, (after.x.segment<3>(3 * i) - before.x.segment<3>(3 * i)).norm());
  }
  return d;
}

std::string ClosureIntegrator::describe_node(int node) const {
  const ValveModel& m = scene_.model;
  if (m.surface_nodes <= 0 || node < 0) return "";
  const int corners = static_cast<int>(m.linear.V.rows());
  if (node >= corners) return " (a mid-edge node)";
  const int i = node % m.surface_nodes, layer = node / m.surface_nodes;
  const bool anterior = m.surface_st(i, 0) < 0.5;
  char buf[160];
  std::snprintf(buf, sizeof buf, " (%s leaflet, s = %.3f, %.0f %% of the way to the free edge, %s",
                anterior ? "anterior" : "posterior", m.surface_st(i, 0), 100.0 * m.surface_st(i, 1),
                layer == 0 ? "atrial surface" : "ventricular side");
  std::string out = buf;
  for (size_t c = 0; c < scene_.grasps.size(); ++c) {
    const ClipGrasp& g = scene_.grasps[c];
    const auto& band = anterior ? g.anterior_band : g.posterior_band;
    if (std::find(band.begin(), band.end(), i) != band.end())
      out += ", grasped by clip " + std::to_string(c + 1);
  }
  return out + ")";
}

// The linearization point was checked when it was linearized; the step's end must be valid
// too, or the next step would start from an inverted element that no smaller step can mend.
StepOutcome ClosureIntegrator::check_trial(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1) {
  if (!x1.allFinite()) return failed(Outcome::kNonFiniteState, "non-finite positions");
  if (const int bad = body_.first_inverted(x1); bad >= 0)
    return failed(Outcome::kInvertedElement, "element " + std::to_string(bad) + " inverted");
  if (contact_ && options_.contact.ccd) {
    const auto tc = Clock::now();
    const int crossing = contact_->find_crossing(x0, x1);
    counters_.contact_s += seconds_since(tc);
    if (crossing >= 0) {
      ++counters_.crossings;
      return failed(Outcome::kLeafletCrossing, "node " + std::to_string(crossing) +
                                                   describe_node(crossing) +
                                                   " would pass through a leaflet surface");
    }
  }
  return {};
}

std::pair<LeafletGrid, LeafletGrid> ClosureIntegrator::leaflet_surfaces(const ValveState& state,
                                                                        int refine) const {
  const AtrialSampler fine = refine <= 1
                                 ? sampler_
                                 : make_atrial_sampler(scene_.model, options_.model.ures * refine,
                                                       (options_.model.vres - 1) * refine + 1);
  return {sample_atrial(fine, state.x),
          sample_atrial(ventricular_sampler(scene_.model, fine), state.x)};
}

ClosureSample ClosureIntegrator::sample(double tau, const ValveState& state) const {
  const int U = options_.model.ures;
  ClosureSample s;
  s.kinetic_energy = 0.5 * state.v.dot(mass_dof_.cwiseProduct(state.v));
  {
    Eigen::VectorXd g;
    ElementRotations r;
    double e = 0.0;
    s.elastic_energy =
        body_.gradient(state.x, &g, &r, &e) < 0 ? e : std::numeric_limits<double>::quiet_NaN();
  }
  s.time_s = tau;
  s.observed_time_s = scene_.observed_time(std::max(tau, 0.0));
  s.la_surface = sample_atrial(sampler_, state.x);
  ValveFrame fr;
  fr.annulus = s.la_surface.points().topRows(U);
  for (int l = 0; l < kNumLandmarks; ++l) {
    const Landmark lm = static_cast<Landmark>(l);
    fr.landmark_observed[l] =
        l <= index(Landmark::kPosteromedialCommissure) && scene_.observed_at_end_diastole(lm);
    fr.landmarks[l] = fr.landmark_observed[l]
                          ? scene_.landmark(lm, std::max(tau, 0.0))
                          : Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  }
  fr.la_surface = s.la_surface;
  const TipToAnnulusPlane t = tip_to_annulus_plane(fr);
  s.anterior_tip_mm = t.anterior_mm;
  s.posterior_tip_mm = t.posterior_mm;
  if (contact_) s.min_contact_distance_mm = contact_->min_distance();
  if (s.la_surface.points().allFinite()) {
    const ClosureMeasures cm = measure_closure(fr.annulus, s.la_surface.triangulate(), 0.25);
    s.orifice_area_mm2 = cm.orifice_area_mm2;
    s.annulus_area_mm2 = cm.annulus_area_mm2;
    s.orifice_components = cm.orifice_components;
  }
  return s;
}

void ClosureIntegrator::strain_and_stress(const Eigen::VectorXd& x, Eigen::VectorXd* strain,
                                          Eigen::VectorXd* stress_mpa) const {
  const TetMesh& linear = scene_.model.linear;
  const Eigen::Index E = linear.T.rows();
  strain->resize(E);
  stress_mpa->resize(E);
  for (Eigen::Index e = 0; e < E; ++e) {
    Eigen::Matrix3d Dm, Ds;
    for (int k = 0; k < 3; ++k) {
      Dm.col(k) = (linear.V.row(linear.T(e, k + 1)) - linear.V.row(linear.T(e, 0))).transpose();
      Ds.col(k) = x.segment<3>(3 * linear.T(e, k + 1)) - x.segment<3>(3 * linear.T(e, 0));
    }
    const Eigen::Matrix3d F = Ds * Dm.inverse();
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
    // Co-rotational strain: S - I with F = R S (S = V Sigma V^T).
    const Eigen::Matrix3d eps =
        svd.matrixV() * (svd.singularValues().asDiagonal()) * svd.matrixV().transpose() -
        Eigen::Matrix3d::Identity();
    (*strain)[e] = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(eps).eigenvalues().maxCoeff();
    Eigen::Matrix<double, 6, 1> ev;
    ev << eps(0, 0), eps(1, 1), eps(2, 2), 2 * eps(1, 2), 2 * eps(0, 2), 2 * eps(0, 1);
    const TransverselyIsotropic& mat =
        scene_.leaflet_material[linear.tag[e] == static_cast<int>(LeafletTag::kAnterior) ? 0 : 1];
    const Eigen::Matrix<double, 6, 1> sv = mat.stiffness(linear.fibre.row(e).transpose()) * ev;
    (*stress_mpa)[e] =
        std::sqrt(0.5 * ((sv[0] - sv[1]) * (sv[0] - sv[1]) + (sv[1] - sv[2]) * (sv[1] - sv[2]) +
                         (sv[2] - sv[0]) * (sv[2] - sv[0])) +
                  3.0 * (sv[3] * sv[3] + sv[4] * sv[4] + sv[5] * sv[5]));
  }
}

double ClosureIntegrator::clip_gap(int c, const Eigen::VectorXd& x) const {
  // The mean distance between the atrial surface nodes of the clip's tied cross-sections.
  double sum = 0.0;
  int n = 0;
  for (size_t k = static_cast<size_t>(first_spring_); k < cables_.size(); ++k) {
    const Cable& cb = cables_[k];
    if (cb.clip != c) continue;
    sum += (x.segment<3>(3 * cb.a.front()) - x.segment<3>(3 * cb.b.front())).norm();
    ++n;
  }
  return n > 0 ? sum / n : 0.0;
}

void ClosureIntegrator::finish(ClosureResult* result) const {
  ClosureSummary& sum = result->summary;
  sum = counters_;
  result->rest_mesh = scene_.model.linear;
  strain_and_stress(result->positions, &result->element_strain, &result->element_stress_mpa);
  const Interpenetration ip = find_interpenetration(scene_.model, result->positions);
  sum.interpenetrating_nodes = static_cast<int>(ip.nodes.size());
  sum.interpenetration_checked = ip.checked;
  sum.guarded_elements = static_cast<int>(rot_.guards.size());
  result->guarded_elements.assign(ever_guarded_.begin(), ever_guarded_.end());
  result->clip_grasps = scene_.grasps;
  // Chordae tensions at the end (the tips where the boundary ends).
  result->chorda_tension_n.clear();
  result->chorda_marginal.clear();
  for (int c = 0; c < first_spring_; ++c) {
    const Cable& cb = cables_[static_cast<size_t>(c)];
    const SceneChorda& sc = scene_.chordae[static_cast<size_t>(c)];
    const Eigen::Vector3d tip = scene_.papillary_tip(cb.tip, scene_.duration());
    const double l = (mean_of(cb.a, result->positions) - tip).norm();
    result->chorda_tension_n.push_back(cb.law->area * cb.law->stress((l - cb.rest) / cb.rest));
    result->chorda_marginal.push_back(sc.marginal ? 1 : 0);
  }
  const StepSolver::Stats& ls = linear_.stats();
  sum.pcg_fallbacks = ls.pcg_fallbacks;
  sum.double_fallbacks = ls.double_fallbacks;
  sum.unconverged_solves = ls.unconverged;
  sum.factorize_s = ls.factorize_s;
  sum.precondition_s = ls.apply_s;
  sum.analyze_s = ls.analyze_s;
  sum.analyses = ls.analyses;
  sum.factorizations = ls.factorizations;
  sum.pcg_iterations = ls.pcg_iterations;
  sum.preconditioner_applications = ls.applications;
  sum.warm_starts = ls.warm_starts;
  sum.warm_accepted = ls.warm_accepted;
  sum.orderings_reused = ls.orderings_reused;
  if (contact_) {
    sum.contact_searches = contact_->searches();
    sum.contact_reused = contact_->reused();
    sum.min_contact_distance_mm = contact_->min_distance();
  }
}

// ---------------------------------------------------------------------------------------------
// The static solve.

StepOutcome ClosureIntegrator::static_forces(const Eigen::VectorXd& x, double tau,
                                             Eigen::VectorXd* f, Eigen::VectorXd* pressure) {
  const auto ta = Clock::now();
  Eigen::VectorXd g, fc;
  double contact_s = 0.0;
  const bool with_contact = contact_ && terms_.contact;
  // At rest: no friction (and no velocity for it).
  const int bad =
      force_pass(x, Eigen::VectorXd::Zero(ndof_), nullptr, &g, nullptr, &fc, &contact_s);
  counters_.contact_s += contact_s;
  if (bad >= 0) {
    counters_.assembly_s += seconds_since(ta) - contact_s;
    return failed(Outcome::kInvertedElement, "element " + std::to_string(bad) + " inverted");
  }
  f->setZero(ndof_);
  if (terms_.elastic) *f -= g;
  if (terms_.springs) add_cable_forces(x, tau, f);
  if (with_contact) *f += fc;
  if (terms_.pressure) {
    if (pressure) {
      pressure->setZero(ndof_);
      add_pressure_forces(x, tau, pressure);
      *f += *pressure;
    } else {
      add_pressure_forces(x, tau, f);
    }
  }
  counters_.assembly_s += seconds_since(ta) - contact_s;
  return {};
}

void ClosureIntegrator::add_pressure_products(const Eigen::VectorXd& p, Eigen::VectorXd* y) const {
  if (static_pressure_ == 0.0) return;
  const Eigen::VectorXd& x = static_x_;
  // Each load node carries -P/6 (a x b + b x c + c x a); the stiffness is minus its derivative:
  // P/6 [c - b]x, P/6 [a - c]x, P/6 [b - a]x with respect to a, b and c (not symmetric).
  for (const PressureFace& pf : scene_.pressure_faces) {
    const Eigen::Vector3d a = x.segment<3>(3 * pf.a), b = x.segment<3>(3 * pf.b),
                          c = x.segment<3>(3 * pf.c);
    const Eigen::Vector3d t =
        (static_pressure_ / 6.0) * ((c - b).cross(Eigen::Vector3d(p.segment<3>(3 * pf.a))) +
                                    (a - c).cross(Eigen::Vector3d(p.segment<3>(3 * pf.b))) +
                                    (b - a).cross(Eigen::Vector3d(p.segment<3>(3 * pf.c))));
    for (int k = 0; k < 3; ++k) y->segment<3>(3 * pf.load[k]) += t;
  }
}

StepOutcome ClosureIntegrator::assemble_static(const Eigen::VectorXd& x, double tau, double shift) {
  const auto t0 = Clock::now();
  if (terms_.elastic) {
    if (const int bad = body_.consistent_tangents(x, rot_, &static_k_); bad >= 0)
      return failed(Outcome::kInvertedElement, "element " + std::to_string(bad) + " inverted");
  }
  static_x_ = x;
  static_pressure_ = terms_.pressure && tau >= 0.0 ? scene_.pressure(tau) : 0.0;
  static_shift_ = shift;
  // The preconditioner's matrix: the symmetric positive definite part (the warped tangent,
  // the cables, contact's diagonal blocks, the shift).
  SymmetricBlockMatrix& system = *system_;
  system.set_zero();
  if (terms_.elastic) body_.assemble_tangent(rot_, 1.0, &system);
  if (terms_.springs) add_cable_cliques(1.0);
  if (contact_ && terms_.contact) {
    contact_->add_diagonal_blocks(1.0, 0.0, &system);
    contact_->linearize_exact(x);
  }
  system.add_diagonal(shift * mass_);
  rot_at_factor_ = rot_;
  node_rotation_current_ = false;
  const double s = seconds_since(t0);
  counters_.matrix_assembly_s += s;
  counters_.assembly_s += s;
  return {};
}

void ClosureIntegrator::multiply_static(const Eigen::VectorXd& pf, Eigen::VectorXd* y) {
  for (size_t i = 0; i < free_dofs_.size(); ++i)
    p_all_[free_dofs_[i]] = pf[static_cast<Eigen::Index>(i)];
  y_all_.setZero();
  if (terms_.elastic) body_.tangents_times(static_k_, p_all_, &y_all_);
  if (terms_.springs) add_cable_products(p_all_, 1.0, &y_all_);
  if (terms_.pressure) add_pressure_products(p_all_, &y_all_);
  if (contact_ && terms_.contact) contact_->multiply_exact(p_all_, &y_all_);
  y->resize(pf.size());
  for (size_t i = 0; i < free_dofs_.size(); ++i) {
    const int d = free_dofs_[i];
    (*y)[static_cast<Eigen::Index>(i)] = y_all_[d] + static_shift_ * mass_dof_[d] * p_all_[d];
  }
}

StepOutcome ClosureIntegrator::solve_static(double tau, ValveState* state) {
  const auto t0 = Clock::now();
  if (contact_) contact_->set_friction(0.0);
  // The smooth contact distance while Newton runs (SelfContactOptions::smooth_mm), the
  // nearest triangle's again for whatever follows.
  struct SmoothScope {
    SelfContact* c;
    explicit SmoothScope(SelfContact* contact) : c(contact) {
      if (c) c->set_smooth(true);
    }
    ~SmoothScope() {
      if (c) c->set_smooth(false);
    }
  } smooth_scope(contact_ ? &*contact_ : nullptr);
  if (!static_linear_) {
    StepSolverOptions so = options_.solver;
    so.kind = LinearSolver::kReusedFactorPcg;
    so.rotated_preconditioner = false;
    so.warm_start = false;
    so.pcg_max_iterations = std::max(so.pcg_max_iterations, 50);
    static_linear_.emplace(so);
    static_linear_->set_threads(options_.threads);
  }
  const StepSolver::Stats before = static_linear_->stats();
  StepSolver::System A{
      [this](const Eigen::VectorXd& p, Eigen::VectorXd* y) { multiply_static(p, y); },
      [this]() -> const Eigen::SparseMatrix<double>& { return system_->lower(); }, nullptr};
  const Eigen::Index m = static_cast<Eigen::Index>(free_dofs_.size());
  Eigen::VectorXd f, fp;
  // The residual r = -f over the free dofs at x, its norm and the pressure load's norm.
  auto residual_at = [&](const Eigen::VectorXd& x, Eigen::VectorXd* r, double* norm,
                         double* load) -> StepOutcome {
    if (StepOutcome o = static_forces(x, tau, &f, &fp); !o.ok()) return o;
    r->resize(m);
    double l2 = 0.0;
    for (Eigen::Index i = 0; i < m; ++i) {
      const int d = free_dofs_[static_cast<size_t>(i)];
      (*r)[i] = -f[d];
      l2 += fp[d] * fp[d];
    }
    *norm = r->norm();
    if (load) *load = std::sqrt(l2);
    return {};
  };
  auto finish_counters = [&](double rn, double load, int iterations) {
    ClosureSummary& c = counters_;
    c.static_iterations += iterations;
    c.static_residual_n = rn;
    c.static_relative_residual = load > 0 ? rn / load : rn;
    c.static_s += seconds_since(t0);
    const StepSolver::Stats& s = static_linear_->stats();
    c.factorizations += s.factorizations - before.factorizations;
    c.analyses += s.analyses - before.analyses;
    c.pcg_iterations += s.pcg_iterations - before.pcg_iterations;
    c.preconditioner_applications += s.applications - before.applications;
    c.factorize_s += s.factorize_s - before.factorize_s;
    c.precondition_s += s.apply_s - before.apply_s;
    c.analyze_s += s.analyze_s - before.analyze_s;
  };

  Eigen::VectorXd x = state->x, r, rt, dx, xt;
  double rn = 0.0, load = 0.0;
  if (StepOutcome o = residual_at(x, &r, &rn, &load); !o.ok()) {
    finish_counters(0.0, 0.0, 0);
    o.message += " at the static solve's start";
    return o;
  }
  const size_t history_start = counters_.static_history.size();  // this solve's |r| from here
  counters_.static_history.push_back(rn);
  const double target = options_.static_tolerance * std::max(load, 1e-300);
  const double step_target_n = kStaticStepResidual * std::max(load, 1e-300);
  const double r0 = rn;
  double mu = 0.0, mu_unit = 0.0;  // the shift, in units of K's mean diagonal over M's
  bool linearized = true;          // the last static_forces() was at x
  bool converged = rn <= target;
  int it = 0;
  std::string why;
  for (; !converged && it < options_.static_max_iterations; ++it) {
    if (!linearized) {
      if (StepOutcome o = residual_at(x, &r, &rn, nullptr); !o.ok()) {
        finish_counters(rn, load, it);
        return o;
      }
      linearized = true;
    }
    if (StepOutcome o = assemble_static(x, tau, mu * mu_unit); !o.ok()) {
      finish_counters(rn, load, it);
      return o;
    }
    if (mu_unit == 0.0) {
      double m_mean = 0.0;
      for (int d : free_dofs_) m_mean += mass_dof_[d];
      m_mean /= static_cast<double>(std::max<size_t>(free_dofs_.size(), 1));
      mu_unit = system_->lower().diagonal().mean() / std::max(m_mean, 1e-300);
    }
    // Inexact Newton: the linear tolerance follows the residual (quadratic convergence near the
    // solution), at most 0.1.
    static_linear_->set_tolerance(std::clamp(rn / r0, 1e-10, 0.1));
    const auto ts = Clock::now();
    const double matrix_before = counters_.matrix_assembly_s;
    const bool solved = static_linear_->solve_nonsymmetric(A, -r, &dx, &why);
    counters_.solve_s += seconds_since(ts) - (counters_.matrix_assembly_s - matrix_before);
    // The line search on the energy's slope along dx, phi(s) = r(x + s dx) . dx (the residual
    // is the energy's gradient but for the follower pressure's small nonconservative part):
    // phi(0) < 0 for a descent direction; a step is taken where |phi| has fallen to 0.9 of
    // |phi(0)| (or phi is still negative at the full step), the next trial by the secant
    // through phi(0) and phi(s). Not on |r|: the membrane's stiff in-plane dofs make |r| rise
    // along a right step across the soft out-of-plane modes, so a search on |r| crawls
    // (docs/forward-status.md). Every trial keeps the elements uninverted and no node through a
    // leaflet (check_trial); the last admissible trial is taken when none satisfies the test.
    // Along a direction that does not descend, halving until |r| falls.
    const bool usable = solved && dx.allFinite();
    const double phi0 = usable ? r.dot(dx) : 0.0;
    const bool descends = phi0 < 0.0;
    double s = 1.0, taken = 0.0;
    for (int ls = 0; usable && ls < kStaticLineSearch; ++ls) {
      xt = x;
      for (Eigen::Index i = 0; i < m; ++i) xt[free_dofs_[static_cast<size_t>(i)]] += s * dx[i];
      double rtn = 0.0;
      linearized = false;
      if (!check_trial(x, xt).ok() || !residual_at(xt, &rt, &rtn, nullptr).ok()) {
        s *= 0.5;
        continue;
      }
      // A trial that lowers |r| is always taken (Newton's own test: near the solution the slope
      // r . dx is round-off); otherwise, along a descent direction, the slope's test.
      const double phi = rt.dot(dx);
      const bool slope_ok =
          descends && rtn <= kStaticResidualGrowth * rn &&
          (phi < 0.0 || std::abs(phi) <= 0.9 * std::abs(phi0) || ls + 1 == kStaticLineSearch);
      if (rtn < rn || slope_ok) {
        taken = s;
        linearized = true;
        x.swap(xt);
        r.swap(rt);
        rn = rtn;
        break;
      }
      s = descends ? std::clamp(s * phi0 / (phi0 - phi), 0.1 * s, 0.9 * s) : 0.5 * s;
    }
    counters_.static_history.push_back(rn);
    ++counters_.newton_iterations;
    // Converged on the force residual, or (contact's closest features switch between facets,
    // which leaves a residual Newton cannot lower by more than a little per step) when a step
    // was taken along a Newton correction that moves no node by more than static_step_mm, with
    // the residual below kStaticStepResidual of the load.
    const double correction_mm = usable ? dx.lpNorm<Eigen::Infinity>() : 0.0;
    counters_.static_step_mm = correction_mm;
    converged = rn <= target ||
                (taken > 0.0 && correction_mm <= options_.static_step_mm && rn <= step_target_n);
    // The Levenberg shift as a trust region: a full step relaxes it, a short one or a
    // direction that does not descend tightens it.
    if (taken == 1.0) {
      mu = mu < 1e-5 ? 0.0 : mu / 4.0;
    } else if (taken >= 0.25) {
      // keep
    } else if (taken > 0.0) {
      mu = std::max(4.0 * mu, 1e-4);
    } else {
      mu = std::max(10.0 * mu, 1e-3);
      if (mu > 1e4) {
        ++it;
        why = "no step lowers the residual (Levenberg shift past 1e4)";
        break;
      }
    }
    if (!converged && static_stalled(std::span(counters_.static_history).subspan(history_start))) {
      ++it;
      why = "stalled: the residual has not halved in " + std::to_string(kStaticStallIterations) +
            " iterations";
      break;
    }
  }
  finish_counters(rn, load, it);
  if (!converged) {
    // The state is left as it was given (velocity and all): the caller settles from there, as
    // it would have without the static solve. Neither the residual nor the energy tells
    // whether an unconverged iterate lies nearer the rest state: on virtual patient 1 of bench
    // closure (static_start_mm = 0.3) Newton ended at a twentieth of its start residual, and
    // settling from that iterate ended 0.77 mm mean (5.1 mm max) from rest.
    return failed(Outcome::kLinearSolver, "the static solve did not converge: residual " +
                                              std::to_string(rn) + " N (" +
                                              std::to_string(rn / std::max(load, 1e-300)) +
                                              " of the pressure load) after " + std::to_string(it) +
                                              " Newton iterations, last correction " +
                                              std::to_string(counters_.static_step_mm) + " mm" +
                                              (why.empty() ? "" : " (" + why + ")"));
  }
  state->x = x;
  state->v.setZero();
  return {};
}

bool ClosureIntegrator::static_stalled(std::span<const double> history) {
  const size_t n = history.size();
  const size_t w = static_cast<size_t>(kStaticStallIterations);
  if (n <= w) return false;
  const auto lowest = [&](size_t end) {
    return *std::min_element(history.begin(), history.begin() + static_cast<std::ptrdiff_t>(end));
  };
  return lowest(n) > 0.5 * lowest(n - w);
}

}  // namespace mvtwin::forward
