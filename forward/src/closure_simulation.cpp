#include "mvtwin/forward/closure_simulation.h"

#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <sstream>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SVD>

#include "mvtwin/core/annulus_plane.h"
#include "mvtwin/core/closure_measures.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/units.h"
#include "mvtwin/forward/chorda.h"
#include "mvtwin/forward/closure_scene.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/forward/interpenetration.h"
#include "mvtwin/forward/self_contact.h"
#include "mvtwin/forward/symmetric_block_matrix.h"

namespace mvtwin::forward {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

bool ClosureOptions::is_valid(std::string* error) const {
  if (!model.is_valid(error)) return false;
  auto bad = [&](const std::string& m) {
    *error = m;
    return false;
  };
  if (!(dt > 0 && dt <= 0.5)) return bad("dt must be in (0, 0.5] s");
  if (!(stretch > 0 && stretch <= 1000)) return bad("stretch must be in (0, 1000]");
  if (!(density > 0)) return bad("density must be positive");
  if (!(rayleigh_mass >= 0 && rayleigh_stiffness >= 0))
    return bad("Rayleigh coefficients must be >= 0");
  if (!(pcg_tolerance > 0 && pcg_tolerance < 1) || pcg_max_iterations < 1)
    return bad("pcg_tolerance must be in (0, 1) and pcg_max_iterations >= 1");
  if (refactor_iterations < 1) return bad("refactor_iterations must be >= 1");
  if (!(inversion_guard >= 0 && inversion_guard < 1))
    return bad("inversion_guard must be in [0, 1) (0: off)");
  if (!(clip_closing_s > 0 && clip_closing_s <= 100))
    return bad("clip_closing_s must be in (0, 100] s");
  for (const ClipOptions& c : clips) {
    if (!(c.anterior_s >= 0 && c.anterior_s <= 1 && c.posterior_s >= 0 && c.posterior_s <= 1 &&
          c.anterior_t >= 0 && c.anterior_t <= 1 && c.posterior_t >= 0 && c.posterior_t <= 1))
      return bad("clip sites must have s and t in [0, 1]");
    if ((c.anterior_s < 0.5) == (c.posterior_s < 0.5))
      return bad("a clip joins the anterior (s < 0.5) and the posterior (s >= 0.5) leaflet");
    if (!(c.stiffness_n_per_mm > 0 && c.stiffness_n_per_mm < 1e4))
      return bad("clip stiffness must be in (0, 1e4) N/mm");
  }
  if (!(contact_wall_factor >= 0 && contact_wall_factor <= 1e4))
    return bad("contact_wall_factor must be in [0, 1e4]");
  if (newton_iterations < 1 || newton_iterations > 100)
    return bad("newton_iterations must be in 1..100");
  if (!(newton_tolerance > 0)) return bad("newton_tolerance must be positive");
  if (!(contact_alarm_mm > contact_distance_mm && contact_distance_mm >= 0 &&
        contact_alarm_mm <= 5))
    return bad("contact distances must satisfy 0 <= contact < alarm <= 5 mm");
  if (!(contact_friction >= 0 && contact_friction <= 5)) return bad("friction must be in [0, 5]");
  if (!(contact_stiffness_factor >= 1 && contact_stiffness_factor <= 1000))
    return bad("contact_stiffness_factor must be in [1, 1000]");
  if (max_step_halvings < 0 || max_step_halvings > 10)
    return bad("max_step_halvings must be in 0..10");
  for (int k : ruptured_marginal_chordae) {
    if (k < 0 || k >= model.marginal_chordae) return bad("ruptured chorda index out of range");
  }
  return true;
}

std::string ClosureSummary::brief_report() const {
  std::ostringstream os;
  os << (status == ClosureStatus::kConverged ? "closure simulated" : "closure FAILED: " + reason)
     << "; " << steps << " steps (" << halvings << " halvings, " << crossings
     << " crossings caught, " << newton_iterations
     << " Newton iterations), " << dofs << " dofs, " << elements << " elements; " << wall_s
     << " s (assembly " << assembly_s << ", solve " << solve_s << ", contact " << contact_s
     << ", other " << other_s << "); linear solver: " << factorizations << " factorizations, "
     << analyses << " analyses, " << pcg_iterations << " PCG iterations, " << unconverged_solves
     << " unconverged; contact: " << contacts
     << " pairs at the end (max " << max_contacts << ", closest " << min_contact_distance_mm
     << " mm), " << contact_searches << " searches, "
     << contact_reused << " reused the candidate list; " << interpenetrating_nodes << " of "
     << interpenetration_checked << " surface nodes inside the other leaflet; " << guarded_elements
     << " elements held by the inversion guard";
  return os.str();
}

ClosureResult simulate_closure(const ValveSequence& seq, const ValveParameters& params,
                               const ClosureOptions& opt) {
  const auto t_start = Clock::now();
  const ClosureScene scene = make_closure_scene(seq, params, opt);  // validates the options
  const ValveModel& model = scene.model;
  const SolidMesh& mesh = model.mesh;
  ElasticBody body(mesh, [&](int tag) {
    return scene.leaflet_material[tag == static_cast<int>(LeafletTag::kAnterior) ? 0 : 1];
  });
  body.set_inversion_guard(opt.inversion_guard);
  const int n = mesh.num_nodes(), ndof = 3 * n;
  const int U = opt.model.ures, V = opt.model.vres;
  const double T = scene.duration();

  // Two-point force elements: chordae (to a papillary tip) and clip springs (between two
  // cross-sections); each end is the mean of a node set or a prescribed point.
  struct Cable {
    std::vector<int> a, b;  // node sets; b empty: the far end is papillary tip `tip`
    int tip = -1;
    double rest = 0.0;
    const ChordaLaw* law = nullptr;  // null: linear spring of stiffness k
    double k = 0.0;
  };
  std::vector<Cable> cables;
  for (const SceneChorda& c : scene.chordae) cables.push_back({c.nodes, {}, c.tip, c.rest_length, &c.law, 0.0});
  const int first_spring = static_cast<int>(cables.size());
  for (const SceneSpring& sp : scene.springs)
    cables.push_back({sp.a, sp.b, -1, sp.rest_length, nullptr, sp.stiffness});

  std::vector<char> fixed(ndof, 0);
  for (const PrescribedNode& pr : scene.prescribed)
    fixed[3 * pr.node] = fixed[3 * pr.node + 1] = fixed[3 * pr.node + 2] = 1;
  std::vector<int> free_dofs;
  for (int i = 0; i < ndof; ++i) {
    if (!fixed[i]) free_dofs.push_back(i);
  }
  const Eigen::VectorXd X = body.rest_positions();

  const Eigen::VectorXd mass = body.lumped_mass(opt.density);
  Eigen::VectorXd mass_dof(ndof);
  for (int i = 0; i < ndof; ++i) mass_dof[i] = mass[i / 3];
  ClosureResult result;
  ClosureSummary& sum = result.summary;
  sum.dofs = static_cast<int>(free_dofs.size());
  sum.elements = mesh.num_elements();

  std::optional<SelfContact> contact;
  if (opt.contact) {
    SelfContact::Options co;
    co.alarm_mm = opt.contact_alarm_mm;
    co.contact_mm = opt.contact_distance_mm;
    co.friction = opt.contact_friction;
    co.wall_factor = opt.contact_wall_factor;
    co.max_depth_mm = 0.5 * std::min(opt.model.al_thickness_mm, opt.model.pl_thickness_mm);
    co.stiffness_per_area = opt.contact_stiffness_factor *
                            std::max(params.peak_pressure_mpa, units::mmhg_to_mpa(10.0)) /
                            (opt.contact_alarm_mm - opt.contact_distance_mm);
    contact.emplace(SelfContact::valve_surface(model), co);
  }
  const AtrialSampler sampler = make_atrial_sampler(model, U, V);
  auto record = [&](double tau, const Eigen::VectorXd& x, const Eigen::VectorXd& vel) {
    ClosureSample s;
    s.kinetic_energy = 0.5 * vel.dot(mass_dof.cwiseProduct(vel));
    {
      Eigen::VectorXd g;
      ElementRotations r;
      double e = 0.0;
      s.elastic_energy =
          body.gradient(x, &g, &r, &e) < 0 ? e : std::numeric_limits<double>::quiet_NaN();
    }
    s.time_s = tau;
    s.observed_time_s = scene.observed_time(std::max(tau, 0.0));
    s.la_surface = sample_atrial(sampler, x);
    ValveFrame fr;
    fr.annulus = s.la_surface.points().topRows(U);
    for (int l = 0; l < kNumLandmarks; ++l) {
      const Landmark lm = static_cast<Landmark>(l);
      fr.landmark_observed[l] =
          l <= index(Landmark::kPosteromedialCommissure) && scene.observed_at_end_diastole(lm);
      fr.landmarks[l] =
          fr.landmark_observed[l] ? scene.landmark(lm, std::max(tau, 0.0))
                                  : Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
    }
    fr.la_surface = s.la_surface;
    const TipToAnnulusPlane t = tip_to_annulus_plane(fr);
    s.anterior_tip_mm = t.anterior_mm;
    s.posterior_tip_mm = t.posterior_mm;
    if (contact) s.min_contact_distance_mm = contact->min_distance();
    if (s.la_surface.points().allFinite()) {
      const ClosureMeasures cm = measure_closure(fr.annulus, s.la_surface.triangulate(), 0.25);
      s.orifice_area_mm2 = cm.orifice_area_mm2;
      s.annulus_area_mm2 = cm.annulus_area_mm2;
      s.orifice_components = cm.orifice_components;
    }
    result.samples.push_back(std::move(s));
  };

  Eigen::VectorXd x = X, v = Eigen::VectorXd::Zero(ndof);
  if (opt.initial_velocity.size() > 0) {
    if (opt.initial_velocity.size() != ndof || !opt.initial_velocity.allFinite()) {
      throw Error("closure options: initial_velocity needs " + std::to_string(ndof) +
                  " finite values (3 per node)");
    }
    v = opt.initial_velocity;
    for (int i = 0; i < ndof; ++i) {
      if (fixed[i]) v[i] = 0.0;
    }
  }

  // The step matrix on a fixed pattern: every element, and each chorda's insertion nodes.
  std::vector<char> node_free(n, 1);
  for (const PrescribedNode& pr : scene.prescribed) node_free[pr.node] = 0;
  std::vector<std::vector<int>> cliques = body.element_cliques();
  const int first_cable_clique = static_cast<int>(cliques.size());
  for (const Cable& cb : cables) {
    std::vector<int> c = cb.a;
    c.insert(c.end(), cb.b.begin(), cb.b.end());
    cliques.push_back(c);
  }
  SymmetricBlockMatrix system(node_free, cliques);
  if (system.rows() != static_cast<int>(free_dofs.size()))
    throw Error("closure simulation: internal error (free dofs and system rows differ)");
  StepSolver linear({opt.solver, opt.pcg_tolerance, opt.pcg_max_iterations,
                     opt.refactor_iterations, opt.single_precision_preconditioner});

  // The linearization of one step: element rotations, each cable's 3x3 tangent (its Hessian
  // with respect to either end point).
  ElementRotations rot, rot_at_factor;
  std::vector<Eigen::Matrix3d> cable_tangent(cables.size());
  // Rotation of each node's neighbourhood since the last factorization (rotated
  // preconditioner, StepSolver::System::rotate), computed when first needed in a linearization.
  std::vector<Eigen::Matrix3d> node_rotation(n);
  bool node_rotation_current = false;
  auto update_node_rotation = [&] {
    for (auto& Q : node_rotation) Q.setZero();
    const int npe = mesh.nodes_per_element();
    for (int e = 0; e < mesh.num_elements(); ++e) {
      const Eigen::Matrix3d D = rot.R[e] * rot_at_factor.R[e].transpose();
      for (int a = 0; a < npe; ++a) node_rotation[mesh.T(e, a)] += D;
    }
    for (auto& Q : node_rotation) {
      Eigen::Matrix3d R, S;
      Q = polar_decomposition(Q, &R, &S) ? R : Eigen::Matrix3d::Identity();
    }
    node_rotation_current = true;
  };
  Eigen::VectorXd p_all = Eigen::VectorXd::Zero(ndof), y_all(ndof);

  // Clip phase (SPEC Sec. 5), simulated time [-clip_closing_s, 0): pressure off, annulus and
  // papillary tips held at end-diastole, each clip's rest length closing smoothly from the
  // sites' distance at rest to its target; the closure then starts from the clipped valve.
  const double clip_phase = scene.springs.empty() ? 0.0 : opt.clip_closing_s;
  std::vector<double> spring_start(cables.size(), 0.0);
  auto mean_of = [](const std::vector<int>& nodes, const Eigen::VectorXd& at) {
    Eigen::Vector3d m = Eigen::Vector3d::Zero();
    for (int k : nodes) m += at.segment<3>(3 * k);
    return Eigen::Vector3d(m / static_cast<double>(nodes.size()));
  };
  for (size_t c = first_spring; c < cables.size(); ++c)
    spring_start[c] = (mean_of(cables[c].a, X) - mean_of(cables[c].b, X)).norm();
  auto cable_rest = [&](size_t c, double tau) {
    if (static_cast<int>(c) < first_spring || tau >= 0.0) return cables[c].rest;
    const double q = 1.0 - std::min(1.0, -tau / clip_phase);  // 0 at the phase's start
    const double w = q * q * (3.0 - 2.0 * q);
    return std::max(cables[c].rest, (1.0 - w) * spring_start[c] + w * cables[c].rest);
  };

  // One implicit Euler step from (x, v) at tau to tau + h; false with a reason on failure.
  auto step = [&](double tau, double h, Eigen::VectorXd* x_io, Eigen::VectorXd* v_io,
                  std::string* why) -> bool {
    const Eigen::VectorXd x0 = *x_io, v0 = *v_io;
    const double tau1 = tau + h;
    const double scene_time = std::max(tau1, 0.0);  // the clip phase holds end-diastole
    const double p = tau1 < 0.0 ? 0.0 : scene.pressure(tau1);
    const Eigen::Vector3d tips[2] = {scene.papillary_tip(0, scene_time),
                                     scene.papillary_tip(1, scene_time)};
    Eigen::VectorXd xp1 = x0;
    scene.prescribed_positions(scene_time, &xp1);
    Eigen::VectorXd v1 = v0;
    for (const PrescribedNode& pr : scene.prescribed)
      v1.segment<3>(3 * pr.node) = (xp1 - x0).segment<3>(3 * pr.node) / h;
    const double ck = h * opt.rayleigh_stiffness + h * h;  // K's factor in the step matrix
    const double cm = 1.0 + h * opt.rayleigh_mass;          // M's factor
    // y = A p over the free dofs, with every coupling (contact included).
    auto multiply = [&](const Eigen::VectorXd& pf, Eigen::VectorXd* y) {
      for (size_t i = 0; i < free_dofs.size(); ++i) p_all[free_dofs[i]] = pf[static_cast<Eigen::Index>(i)];
      y_all.setZero();
      body.tangent_times(rot, p_all, &y_all);
      y_all *= ck;
      for (size_t c = 0; c < cables.size(); ++c) {
        const Cable& cb = cables[c];
        Eigen::Vector3d d = mean_of(cb.a, p_all);
        if (!cb.b.empty()) d -= mean_of(cb.b, p_all);
        const Eigen::Vector3d t = h * h * (cable_tangent[c] * d);
        for (int k : cb.a) y_all.segment<3>(3 * k) += t / static_cast<double>(cb.a.size());
        for (int k : cb.b) y_all.segment<3>(3 * k) -= t / static_cast<double>(cb.b.size());
      }
      if (contact) contact->multiply(p_all, h * h, h, &y_all);
      y->resize(pf.size());
      for (size_t i = 0; i < free_dofs.size(); ++i) {
        const int d = free_dofs[i];
        (*y)[static_cast<Eigen::Index>(i)] = y_all[d] + cm * mass_dof[d] * p_all[d];
      }
    };
    // The factorized matrix: the same without the contact couplings (their diagonal blocks
    // only), assembled only when the solver factorizes.
    auto lower = [&]() -> const Eigen::SparseMatrix<double>& {
      const auto t0 = Clock::now();
      system.set_zero();
      body.assemble_tangent(rot, ck, &system);
      for (size_t c = 0; c < cables.size(); ++c) {
        const Cable& cb = cables[c];
        const int ma = static_cast<int>(cb.a.size()), m = ma + static_cast<int>(cb.b.size());
        Eigen::MatrixXd K(3 * m, 3 * m);
        for (int i = 0; i < m; ++i) {
          const double wi = i < ma ? 1.0 / ma : -1.0 / (m - ma);
          for (int j = 0; j < m; ++j) {
            const double wj = j < ma ? 1.0 / ma : -1.0 / (m - ma);
            K.block<3, 3>(3 * i, 3 * j) = wi * wj * cable_tangent[c];
          }
        }
        system.add_clique(first_cable_clique + static_cast<int>(c), K, h * h);
      }
      if (contact) contact->add_diagonal_blocks(h * h, h, &system);
      system.add_diagonal(cm * mass);
      rot_at_factor = rot;
      node_rotation_current = false;
      sum.matrix_assembly_s += seconds_since(t0);
      return system.lower();
    };
    auto rotate = [&](Eigen::VectorXd* vf, bool transpose) {
      if (!node_rotation_current) update_node_rotation();
      for (int i = 0; i < n; ++i) {
        const int f0 = system.first_row(i);
        if (f0 < 0) continue;
        const Eigen::Vector3d a = vf->segment<3>(f0);
        vf->segment<3>(f0) = transpose ? Eigen::Vector3d(node_rotation[i].transpose() * a)
                                       : Eigen::Vector3d(node_rotation[i] * a);
      }
    };
    StepSolver::System A{multiply, lower, nullptr};
    if (opt.rotated_preconditioner) A.rotate = rotate;

    for (int it = 0; it < opt.newton_iterations; ++it) {
      auto ta = Clock::now();
      const double contact_before = sum.contact_s;
      const Eigen::VectorXd x1 = x0 + h * v1;
      // The elastic gradient and K v1 (for the stiffness-proportional damping) in one pass.
      Eigen::VectorXd g, Kv;
      const int bad = body.gradient(x1, &g, &rot, nullptr, &v1, &Kv);
      node_rotation_current = false;
      if (bad >= 0) {
        *why = "element " + std::to_string(bad) + " inverted";
        return false;
      }
      Eigen::VectorXd f =
          -g - opt.rayleigh_mass * mass_dof.cwiseProduct(v1) - opt.rayleigh_stiffness * Kv;
      for (size_t c = 0; c < cables.size(); ++c) {
        const Cable& cb = cables[c];
        Eigen::Matrix<double, 6, 1> gc;
        Eigen::Matrix<double, 6, 6> Hc;
        const double rest = cable_rest(c, tau1);
        // A clip is a tension-only linear spring: force k (l - L0) as a law in strain.
        const ChordaLaw law = cb.law ? *cb.law : ChordaLaw{1.0, cb.k * rest, cb.k * rest, 1.0};
        const Eigen::Vector3d end = cb.b.empty() ? tips[cb.tip] : mean_of(cb.b, x1);
        chorda_gradient(law, rest, mean_of(cb.a, x1), end, &gc, &Hc);
        for (int k : cb.a) f.segment<3>(3 * k) -= gc.head<3>() / static_cast<double>(cb.a.size());
        for (int k : cb.b) f.segment<3>(3 * k) -= gc.tail<3>() / static_cast<double>(cb.b.size());
        cable_tangent[c] = Hc.topLeftCorner<3, 3>();
      }
      if (contact) {
        const auto tc = Clock::now();
        const int found = contact->detect(x1);
        sum.contacts = found;
        sum.max_contacts = std::max(sum.max_contacts, found);
        contact->add_forces(v1, &f);
        sum.contact_s += seconds_since(tc);
      }
      for (const PressureFace& pf : scene.pressure_faces) {
        const Eigen::Vector3d a = x1.segment<3>(3 * pf.a), b = x1.segment<3>(3 * pf.b),
                              c = x1.segment<3>(3 * pf.c);
        const Eigen::Vector3d force = -p * 0.5 * (b - a).cross(c - a) / 3.0;
        for (int k = 0; k < 3; ++k) f.segment<3>(3 * pf.load[k]) += force;
      }
      Eigen::VectorXd r(free_dofs.size());
      for (size_t i = 0; i < free_dofs.size(); ++i) {
        const int d = free_dofs[i];
        r[static_cast<Eigen::Index>(i)] = mass[d / 3] * (v1[d] - v0[d]) - h * f[d];
      }
      sum.assembly_s += seconds_since(ta) - (sum.contact_s - contact_before);
      auto ts = Clock::now();
      const double matrix_before = sum.matrix_assembly_s;
      Eigen::VectorXd dv;
      const bool solved = linear.solve(A, -r, &dv, why);
      const double matrix_s = sum.matrix_assembly_s - matrix_before;
      sum.solve_s += seconds_since(ts) - matrix_s;
      sum.assembly_s += matrix_s;
      if (!solved) return false;
      for (size_t i = 0; i < free_dofs.size(); ++i)
        v1[free_dofs[i]] += dv[static_cast<Eigen::Index>(i)];
      ++sum.newton_iterations;
      sum.final_update_norm = dv.lpNorm<Eigen::Infinity>();
      if (sum.final_update_norm < opt.newton_tolerance) break;
    }
    const Eigen::VectorXd x_new = x0 + h * v1;
    if (!x_new.allFinite()) {
      *why = "non-finite positions";
      return false;
    }
    // The linearization point was checked above; the step's end must be valid too, or the next
    // step would start from an inverted element that no smaller step can mend.
    if (const int bad = body.first_inverted(x_new); bad >= 0) {
      *why = "element " + std::to_string(bad) + " inverted";
      return false;
    }
    if (contact && opt.contact_ccd) {
      const auto tc = Clock::now();
      const int crossing = contact->find_crossing(x0, x_new);
      sum.contact_s += seconds_since(tc);
      if (crossing >= 0) {
        ++sum.crossings;
        *why = "node " + std::to_string(crossing) + " would pass through a leaflet surface";
        return false;
      }
    }
    *x_io = x_new;
    *v_io = v1;
    return true;
  };

  auto finish = [&] {
    // Per-element strain and stress at the end, from the corner nodes.
    result.rest_mesh = model.linear;
    const Eigen::Index E = model.linear.T.rows();
    result.element_strain.resize(E);
    result.element_stress_mpa.resize(E);
    for (Eigen::Index e = 0; e < E; ++e) {
      Eigen::Matrix3d Dm, Ds;
      for (int k = 0; k < 3; ++k) {
        Dm.col(k) = (model.linear.V.row(model.linear.T(e, k + 1)) -
                     model.linear.V.row(model.linear.T(e, 0))).transpose();
        Ds.col(k) = result.positions.segment<3>(3 * model.linear.T(e, k + 1)) -
                    result.positions.segment<3>(3 * model.linear.T(e, 0));
      }
      const Eigen::Matrix3d F = Ds * Dm.inverse();
      const Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
      // Co-rotational strain: S - I with F = R S (S = V Sigma V^T).
      const Eigen::Matrix3d eps = svd.matrixV() * (svd.singularValues().asDiagonal()) *
                                      svd.matrixV().transpose() -
                                  Eigen::Matrix3d::Identity();
      result.element_strain[e] = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(eps)
                                     .eigenvalues()
                                     .maxCoeff();
      Eigen::Matrix<double, 6, 1> ev;
      ev << eps(0, 0), eps(1, 1), eps(2, 2), 2 * eps(1, 2), 2 * eps(0, 2), 2 * eps(0, 1);
      const TransverselyIsotropic mat =
          model.linear.tag[e] == static_cast<int>(LeafletTag::kAnterior)
              ? TransverselyIsotropic::anterior_leaflet().scaled(params.al_modulus_scale)
              : TransverselyIsotropic::posterior_leaflet().scaled(params.pl_modulus_scale);
      const Eigen::Matrix<double, 6, 1> sv =
          mat.stiffness(model.linear.fibre.row(e).transpose()) * ev;
      const double vm = std::sqrt(0.5 * ((sv[0] - sv[1]) * (sv[0] - sv[1]) +
                                         (sv[1] - sv[2]) * (sv[1] - sv[2]) +
                                         (sv[2] - sv[0]) * (sv[2] - sv[0])) +
                                  3.0 * (sv[3] * sv[3] + sv[4] * sv[4] + sv[5] * sv[5]));
      result.element_stress_mpa[e] = vm;
    }
    {
      const Interpenetration ip = find_interpenetration(model, result.positions);
      sum.interpenetrating_nodes = static_cast<int>(ip.nodes.size());
      sum.interpenetration_checked = ip.checked;
    }
    sum.guarded_elements = static_cast<int>(rot.guards.size());
    sum.pcg_fallbacks = linear.stats().pcg_fallbacks;
    sum.unconverged_solves = linear.stats().unconverged;
    sum.factorize_s = linear.stats().factorize_s;
    sum.analyses = linear.stats().analyses;
    sum.factorizations = linear.stats().factorizations;
    sum.pcg_iterations = linear.stats().pcg_iterations;
    if (contact) {
      sum.contact_searches = contact->searches();
      sum.contact_reused = contact->reused();
      sum.min_contact_distance_mm = contact->min_distance();
    }
    sum.wall_s = seconds_since(t_start);
    sum.other_s = sum.wall_s - sum.assembly_s - sum.solve_s - sum.contact_s;
  };

  double tau = -clip_phase;
  if (tau >= 0.0) record(0.0, x, v);
  int step_index = 0;
  while (tau < T - 1e-12) {
    // Steps land on t = 0, where the clip phase ends and the closure is first recorded.
    double h = std::min(opt.dt, tau < 0.0 ? -tau : T - tau);
    std::string why;
    int halvings = 0;
    Eigen::VectorXd xt = x, vt = v;
    while (!step(tau, h, &xt, &vt, &why)) {
      if (halvings >= opt.max_step_halvings) {
        sum.status = ClosureStatus::kFailed;
        sum.reason = why + " at t = " + std::to_string(tau) + " s" +
                     (tau < 0 ? " (clip phase)" : "") + " (after " + std::to_string(halvings) +
                     " step halvings)";
        result.positions = x;
        record(std::max(tau, 0.0), x, v);
        finish();
        return result;
      }
      ++halvings;
      ++sum.halvings;
      h *= 0.5;
      xt = x;
      vt = v;
    }
    const bool clip_phase_ends = tau < 0.0 && tau + h >= -1e-12;
    x = xt;
    v = vt;
    tau += h;
    ++sum.steps;
    if (clip_phase_ends) {
      tau = 0.0;
      record(0.0, x, v);
      for (size_t c = first_spring; c < cables.size(); ++c)
        result.clip_gap_clipped_mm.push_back(
            (x.segment<3>(3 * cables[c].a.front()) - x.segment<3>(3 * cables[c].b.front())).norm());
      continue;
    }
    if (tau < 0.0) continue;
    ++step_index;
    if (opt.progress) opt.progress(tau, T);
    if (opt.record_every > 0 && step_index % opt.record_every == 0 && tau < T - 1e-12)
      record(tau, x, v);
  }
  record(tau, x, v);
  result.positions = x;
  for (size_t c = first_spring; c < cables.size(); ++c)
    result.clip_gap_end_mm.push_back(
        (x.segment<3>(3 * cables[c].a.front()) - x.segment<3>(3 * cables[c].b.front())).norm());
  sum.status = ClosureStatus::kConverged;
  finish();
  return result;
}

SimulationRecord make_simulation_record(const ClosureResult& r, const ClosureOptions& o,
                                        const ValveParameters& p) {
  SimulationRecord rec;
  rec.options = describe_options(o);
  rec.parameters = p;
  const ClosureSummary& s = r.summary;
  rec.status = s.status == ClosureStatus::kConverged ? "converged" : "failed";
  rec.reason = s.reason;
  rec.summary = {{"steps", s.steps},
                 {"halvings", s.halvings},
                 {"crossings", s.crossings},
                 {"newton_iterations", s.newton_iterations},
                 {"dofs", s.dofs},
                 {"elements", s.elements},
                 {"wall_s", s.wall_s},
                 {"assembly_s", s.assembly_s},
                 {"solve_s", s.solve_s},
                 {"contact_s", s.contact_s},
                 {"other_s", s.other_s},
                 {"contacts", s.contacts},
                 {"max_contacts", s.max_contacts},
                 {"contact_searches", s.contact_searches},
                 {"min_contact_distance_mm", s.min_contact_distance_mm},
                 {"factorizations", s.factorizations},
                 {"pcg_iterations", s.pcg_iterations},
                 {"unconverged_solves", s.unconverged_solves},
                 {"final_update_norm", s.final_update_norm},
                 {"interpenetrating_nodes", s.interpenetrating_nodes},
                 {"guarded_elements", s.guarded_elements},
                 {"interpenetration_checked", s.interpenetration_checked}};
  for (const ClosureSample& c : r.samples) {
    rec.time_s.push_back(c.time_s);
    rec.observed_time_s.push_back(c.observed_time_s);
    rec.anterior_tip_mm.push_back(c.anterior_tip_mm);
    rec.posterior_tip_mm.push_back(c.posterior_tip_mm);
    rec.orifice_area_mm2.push_back(c.orifice_area_mm2);
    rec.annulus_area_mm2.push_back(c.annulus_area_mm2);
    rec.la_surface.push_back(c.la_surface);
  }
  rec.mesh = r.rest_mesh;
  const Eigen::Index N = r.rest_mesh.V.rows();
  rec.final_positions.resize(N, 3);
  for (Eigen::Index i = 0; i < N; ++i) rec.final_positions.row(i) = r.positions.segment<3>(3 * i).transpose();
  rec.element_strain = r.element_strain;
  rec.element_stress_mpa = r.element_stress_mpa;
  return rec;
}

}  // namespace mvtwin::forward
