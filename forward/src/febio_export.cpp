#include "mvtwin/forward/febio_export.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include <Eigen/Geometry>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"

namespace mvtwin::forward {
namespace {

std::string num(double x) {
  std::ostringstream os;
  os.precision(12);
  os << x;
  return os.str();
}

std::string vec(const Eigen::Vector3d& v) {
  return num(v.x()) + "," + num(v.y()) + "," + num(v.z());
}

/// XML comments may not contain "--".
std::string comment_safe(std::string s) {
  for (size_t i = s.find("--"); i != std::string::npos; i = s.find("--")) s.replace(i, 2, "- -");
  return s;
}

/// A unit vector orthogonal to a (the material's second axis; any choice is equivalent for a
/// transversely isotropic material).
Eigen::Vector3d orthogonal(const Eigen::Vector3d& a) {
  Eigen::Index k;
  a.cwiseAbs().minCoeff(&k);
  return a.cross(Eigen::Vector3d(Eigen::Vector3d::Unit(k))).normalized();
}

}  // namespace

std::vector<std::pair<double, double>> febio_spring_curve(double initial, double rest,
                                                          const ChordaLaw* law, double k) {
  // The spring's strain is (initial + DL - rest) / rest; no force in compression.
  const double slack = rest - initial;  // DL at which the spring becomes taut
  std::vector<std::pair<double, double>> pts = {{std::min(slack, 0.0) - initial, 0.0},
                                                {slack, 0.0}};
  if (law) {
    const double eb = law->strain_break;
    pts.emplace_back(slack + eb * rest, law->area * law->stress(eb));
    pts.emplace_back(slack + 2.0 * rest, law->area * law->stress(2.0));
  } else {
    pts.emplace_back(slack + rest, k * rest);
  }
  return pts;
}

FebioContactPotential febio_contact_potential(const SelfContactOptions& contact,
                                              double stiffness_per_area, double peak_pressure_mpa) {
  FebioContactPotential cp;
  cp.r_in = kFebioContactRangeFactor * contact.contact_mm;
  cp.r_out = kFebioContactRangeFactor * contact.alarm_mm;
  cp.r0_min = contact.exclusion_mm * contact.exclusion_mm;
  // Pressure at gap g in [R_in, R_out) between parallel surfaces: (2 pi / 3) c1 g (R_out - g)^3;
  // equal to k (R_out - R_in) at g = R_in: c1 = 3 k / (2 pi R_in (R_out - R_in)^2), and FEBio's
  // c1 = p kc / (2 (R_out - R_in) R_in^(p + 1)).
  const double w = cp.r_out - cp.r_in;
  const double c1 = 3.0 * stiffness_per_area / (2.0 * M_PI * cp.r_in * w * w);
  cp.kc = 2.0 * c1 * w * std::pow(cp.r_in, cp.p + 1.0) / cp.p;
  // The gap at which it presses with the peak pressure: P(g) / P(R_in) = g (R_out - g)^3 /
  // (R_in w^3) decreases on [R_in, R_out) (its maximum is at R_out / 4 < R_in), so bisect.
  const double target = peak_pressure_mpa / (stiffness_per_area * w);
  double lo = cp.r_in, hi = cp.r_out;
  for (int i = 0; i < 100; ++i) {
    const double g = 0.5 * (lo + hi);
    (g * std::pow(cp.r_out - g, 3) / (cp.r_in * w * w * w) > target ? lo : hi) = g;
  }
  cp.gap_at_peak = 0.5 * (lo + hi);
  cp.mvtwin_gap_at_peak = contact.alarm_mm - peak_pressure_mpa / stiffness_per_area;
  return cp;
}

std::vector<FebioChordaSpring> febio_chorda_springs(const ClosureScene& scene, int chorda) {
  const SceneChorda& ch = scene.chordae.at(static_cast<size_t>(chorda));
  const SolidMesh& mesh = scene.model.mesh;
  const Eigen::Vector3d tip = scene.papillary_tip(ch.tip, 0.0);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int i : ch.nodes) mean += mesh.V.row(i).transpose();
  mean /= static_cast<double>(ch.nodes.size());
  const double mean_length = (mean - tip).norm();
  std::vector<FebioChordaSpring> out;
  for (int i : ch.nodes) {
    const double initial = (mesh.V.row(i).transpose() - tip).norm();
    out.push_back(
        {i, 1.0 / static_cast<double>(ch.nodes.size()), initial, mean_length, ch.rest_length});
  }
  return out;
}

std::vector<int> febio_node_order(const SolidMesh& mesh) {
  const int n = mesh.num_nodes(), npe = mesh.nodes_per_element();
  std::vector<std::set<int>> adj(static_cast<size_t>(n));
  for (int e = 0; e < mesh.num_elements(); ++e)
    for (int a = 0; a < npe; ++a)
      for (int b = 0; b < npe; ++b)
        if (a != b) adj[mesh.T(e, a)].insert(mesh.T(e, b));
  auto degree = [&](int i) { return adj[i].size(); };
  std::vector<int> order;
  std::vector<char> seen(static_cast<size_t>(n), 0);
  // Breadth-first from `start`, neighbours by increasing degree; returns the last level's node
  // of least degree (a pseudo-peripheral node when started from one).
  auto bfs = [&](int start, std::vector<int>* out) {
    std::vector<char> mark(static_cast<size_t>(n), 0);
    std::vector<int> level{start}, all;
    mark[start] = 1;
    int last = start;
    while (!level.empty()) {
      std::vector<int> next;
      for (int i : level) {
        all.push_back(i);
        std::vector<int> nb;
        for (int j : adj[i])
          if (!mark[j] && !seen[j]) nb.push_back(j);
        std::stable_sort(nb.begin(), nb.end(), [&](int x, int y) { return degree(x) < degree(y); });
        for (int j : nb) {
          mark[j] = 1;
          next.push_back(j);
        }
      }
      if (!next.empty()) {
        last = *std::min_element(next.begin(), next.end(),
                                 [&](int x, int y) { return degree(x) < degree(y); });
      }
      level = std::move(next);
    }
    if (out) *out = all;
    return last;
  };
  for (int s = 0; s < n; ++s) {
    if (seen[s]) continue;
    int start = s;
    for (int i = s; i < n; ++i)  // least degree node of this component first
      if (!seen[i] && degree(i) < degree(start)) start = i;
    start = bfs(bfs(start, nullptr), nullptr);
    std::vector<int> comp;
    bfs(start, &comp);
    for (int i : comp) seen[i] = 1;
    order.insert(order.end(), comp.begin(), comp.end());
  }
  std::reverse(order.begin(), order.end());
  return order;
}

std::vector<RimFace> rim_faces(const ClosureScene& scene) {
  const ValveModel& m = scene.model;
  const SolidMesh& mesh = m.mesh;
  std::vector<char> held(static_cast<size_t>(mesh.num_nodes()), 0);
  for (const PrescribedNode& p : scene.prescribed) held[p.node] = 1;
  const int surface = m.surface_nodes, layers = m.options.layers;
  auto layer = [&](int corner) { return corner / surface; };
  constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  std::map<std::array<int, 3>, std::pair<int, int>> faces;  // sorted corners -> (element, face)
  for (int e = 0; e < mesh.num_elements(); ++e) {
    for (int f = 0; f < 4; ++f) {
      std::array<int, 3> k = {mesh.T(e, kFace[f][0]), mesh.T(e, kFace[f][1]),
                              mesh.T(e, kFace[f][2])};
      std::sort(k.begin(), k.end());
      auto [it, fresh] = faces.try_emplace(k, e, f);
      if (!fresh) it->second.first = -1;  // shared by two elements: inside
    }
  }
  std::vector<RimFace> out;
  for (const auto& [k, ef] : faces) {
    const auto [e, f] = ef;
    if (e < 0) continue;
    const int a = mesh.T(e, kFace[f][0]), b = mesh.T(e, kFace[f][1]), c = mesh.T(e, kFace[f][2]);
    const int la = layer(a);
    if (la == layer(b) && la == layer(c) && (la == 0 || la == layers)) continue;  // a surface
    if (held[a] && held[b] && held[c]) continue;                                  // the annulus
    // kFace lists each face counter-clockwise seen from outside the element.
    out.push_back({a, b, c, mesh.tag[e] == static_cast<int>(LeafletTag::kAnterior) ? 0 : 1});
  }
  return out;
}

void write_febio(const std::filesystem::path& path, const ClosureScene& scene,
                 const ClosureOptions& opt, const std::string& comment,
                 const std::vector<int>& guarded) {
  const ValveModel& m = scene.model;
  const SolidMesh& mesh = m.mesh;
  const bool quadratic = mesh.order == TetOrder::kQuadratic;
  const int n = mesh.num_nodes();
  const double T = scene.duration();
  // mvtwin's stiffness-proportional damping (C = alpha_K K) as a Maxwell branch of the leaflets'
  // material (FEBio's "viscoelastic": g1 = 1, t1 = alpha_K, so that at a steady strain rate it
  // adds the stress alpha_K K de/dt as the damping does), and after the closure a second
  // analysis step with the loads held (kFebioRelaxTimes x t1 in kFebioRelaxSteps steps) in which
  // the branch relaxes and the soft modes creep to rest: the end state is the scene's rest, as
  // mvtwin's settled closure.
  const double maxwell_t1 = opt.rayleigh_stiffness;
  const double hold_s = maxwell_t1 > 0 ? kFebioRelaxTimes * maxwell_t1 : 0.0;
  // FEBio ids: leaflet nodes in reverse Cuthill-McKee order, then the papillary tips.
  const std::vector<int> order = febio_node_order(mesh);
  std::vector<int> id_of(static_cast<size_t>(n));
  for (int k = 0; k < n; ++k) id_of[order[k]] = k + 1;
  auto nid = [&](int node) { return id_of[static_cast<size_t>(node)]; };
  // Load curves sampled often enough for the C1 motion between frames and the smoothstep.
  const int samples = 41;
  auto sample_time = [&](int k) { return T * k / (samples - 1); };

  std::ostringstream lc;  // LoadData
  int curves = 0;
  auto add_curve = [&](const std::string& name, const std::vector<std::pair<double, double>>& pts,
                       const char* extend) {
    ++curves;
    lc << "    <load_controller id=\"" << curves << "\" name=\"" << name
       << "\" type=\"loadcurve\">\n      <interpolate>LINEAR</interpolate>\n      <extend>"
       << extend << "</extend>\n      <points>\n";
    for (const auto& [t, v] : pts) lc << "        <pt>" << num(t) << "," << num(v) << "</pt>\n";
    lc << "      </points>\n    </load_controller>\n";
    return curves;
  };

  std::ostringstream os;
  os << "<?xml version=\"1.0\" encoding=\"ISO-8859-1\"?>\n<!--\n"
     << comment_safe(comment) << "\n"
     << "Units: mm, s, N, MPa, t (tonne). Written by mvtwin write_febio (docs/febio-export.md).\n"
     << "Not expressible in FEBio and therefore not in this file: the mass-proportional Rayleigh\n"
     << "damping (alpha_M = " << num(opt.rayleigh_mass)
     << " 1/s; the analysis is quasi-static), the stiffness-proportional one (alpha_K = "
     << num(opt.rayleigh_stiffness)
     << " s)\nexcept as a Maxwell branch of the leaflets' material (viscoelastic, g1 = 1, t1 = "
        "alpha_K) with\nthe load held "
     << num(hold_s)
     << " s after the closure (step \"relax\") for it to relax,\n"
        "self-contact within one leaflet, the\n"
     << "contact wall below the minimum distance (wall factor " << num(opt.contact.wall_factor)
     << "; FEBio's potential has its own wall, kc / r^p, below R_in), friction ("
     << num(opt.contact.friction) << " in mvtwin, regularized below a slip of "
     << num(opt.contact.friction_slip_mm_per_s)
     << " mm/s: a drag that a static analysis has no velocity for, and that vanishes at rest),\n"
     << "the inversion guard, the clip phase.\n"
     << "Choices: the leaflets as FEBio's neo-Hookean transiso with mvtwin's constants (the same\n"
     << "stiffness at small strain; unlike St Venant-Kirchhoff it does not soften in compression\n"
     << "and resists collapse, as J -> 0, in place of the inversion guard); nodes numbered by\n"
     << "reverse Cuthill-McKee for a small skyline profile (node set mvtwin_order lists the FEBio\n"
     << "id of mvtwin's nodes 0, 1, ... in order); an automatic time stepper that halves failed\n"
     << "steps (aggressiveness 1, 10 retries: dt / 1024); leaflet contact as FEBio's contact\n"
     << "potential between the leaflets' atrial, ventricular and rim (free edge, commissural)\n"
     << "faces: mvtwin's penalty law with its distances doubled (R_in = 2 x the contact distance,\n"
     << "R_out = 2 x the alarm distance, pressure k (R_out - R_in) at R_in), because the "
        "potential\n"
     << "acts between integration points and a range near their spacing made the static solve\n"
     << "stall in contact; the leaflets therefore coapt farther apart than in mvtwin (the gaps at\n"
     << "peak pressure are in the comment beside the contact); mvtwin's 4 mm neighbour\n"
     << "exclusion; each chorda pulls its whole\n"
     << "cross-section, one spring of 1/k of the force per node, whose curve reads the node's\n"
     << "elongation as the mean point's (mvtwin pulls the mean point: equal while the section\n"
     << "does not rotate). FEBio 4 compares R0_min with the squared reference distance, hence\n"
     << "R0_min = 4^2 mm^2.\n-->\n";
  os << "<febio_spec version=\"4.0\">\n  <Module type=\"solid\"/>\n";
  // An analysis step's Control: `steps` steps of h, each halved up to 10 times on failure.
  // FEBio 4 wants the stepper and solver typed at the top level and refuses the type inside a
  // <step>. aggressiveness 1: a failed step is retried at cutback x h. With 0, FEBio ignores the
  // cutback and shortens the step by h / (max_retries + 1) per retry (FETimeStepController::
  // Retry), so 25 retries never got below dt / 26. Ten halvings reach dtmin = h / 1024; FEBio
  // does not stop a retried step at dtmin, and patient 3 spent 25 retries down to 1e-13 s.
  auto control = [&](const std::string& in, int steps, double h, bool top) {
    os << in << "<Control>\n"
       << in << "  <analysis>STATIC</analysis>\n"
       << in << "  <time_steps>" << steps << "</time_steps>\n"
       << in << "  <step_size>" << num(h) << "</step_size>\n"
       << in << "  <time_stepper" << (top ? " type=\"default\"" : "") << ">\n"
       << in << "    <max_retries>10</max_retries>\n"
       << in << "    <opt_iter>10</opt_iter>\n"
       << in << "    <dtmin>" << num(h / 1024.0) << "</dtmin>\n"
       << in << "    <dtmax>" << num(h) << "</dtmax>\n"
       << in << "    <aggressiveness>1</aggressiveness>\n"
       << in << "    <cutback>0.5</cutback>\n"
       << in << "  </time_stepper>\n"
       << in << "  <solver" << (top ? " type=\"solid\"" : "") << ">\n"
       << in << "    <symmetric_stiffness>symmetric</symmetric_stiffness>\n"
       << in << "    <optimize_bw>1</optimize_bw>\n"
       << in << "  </solver>\n"
       << in << "</Control>\n";
  };
  control("  ", static_cast<int>(std::ceil(T / opt.dt - 1e-9)), opt.dt, true);

  // Materials.
  const char* names[2] = {"anterior_leaflet", "posterior_leaflet"};
  os << "  <Material>\n";
  // A material, wrapped in the Maxwell branch when there is damping to stand for.
  auto material = [&](int id, const char* name, const char* type, const std::string& params) {
    os << "    <material id=\"" << id << "\" name=\"" << name << "\" type=\""
       << (maxwell_t1 > 0 ? "viscoelastic" : type) << "\">\n      <density>" << num(opt.density)
       << "</density>\n";
    if (maxwell_t1 > 0) {
      os << "      <g1>1</g1>\n      <t1>" << num(maxwell_t1) << "</t1>\n      <elastic type=\""
         << type << "\">\n"
         << params << "      </elastic>\n";
    } else {
      os << params;
    }
    os << "    </material>\n";
  };
  for (int k = 0; k < 2; ++k) {
    const TransverselyIsotropic& t = scene.leaflet_material[k];
    material(k + 1, names[k], "neo-Hookean transiso",
             "      <Ep>" + num(t.e_cross) + "</Ep>\n      <Ez>" + num(t.e_fibre) +
                 "</Ez>\n      <vz>" + num(t.nu_fibre) + "</vz>\n      <vp>" + num(t.nu_cross) +
                 "</vp>\n      <gz>" + num(t.g_fibre) + "</gz>\n");
  }
  // Elements the inversion guard held: neo-Hookean, domains of their own (ids 3 and 4).
  std::vector<char> is_guarded(static_cast<size_t>(mesh.num_elements()), 0);
  for (int e : guarded)
    if (e >= 0 && e < mesh.num_elements()) is_guarded[static_cast<size_t>(e)] = 1;
  const char* guarded_names[2] = {"anterior_guarded", "posterior_guarded"};
  for (int k = 0; k < 2; ++k) {
    const TransverselyIsotropic& t = scene.leaflet_material[k];
    material(k + 3, guarded_names[k], "neo-Hookean",
             "      <E>" + num(t.e_cross) + "</E>\n      <v>" + num(t.nu_cross) + "</v>\n");
  }
  os << "  </Material>\n";

  // Mesh: leaflet nodes 1..n, papillary tips n+1, n+2.
  os << "  <Mesh>\n    <Nodes name=\"leaflets\">\n";
  for (int k = 0; k < n; ++k)
    os << "      <node id=\"" << k + 1 << "\">" << vec(mesh.V.row(order[k]).transpose())
       << "</node>\n";
  os << "    </Nodes>\n    <Nodes name=\"papillary_tips\">\n";
  for (int k = 0; k < 2; ++k)
    os << "      <node id=\"" << n + 1 + k << "\">" << vec(scene.papillary_tip(k, 0.0))
       << "</node>\n";
  os << "    </Nodes>\n";
  const int npe = mesh.nodes_per_element();
  // Domains 0, 1: the leaflets (neo-Hookean transiso); 2, 3: their guarded elements (neo-Hookean).
  std::vector<int> elements_of[4];
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const int leaflet = mesh.tag[e] == static_cast<int>(LeafletTag::kAnterior) ? 0 : 1;
    elements_of[leaflet + (is_guarded[static_cast<size_t>(e)] ? 2 : 0)].push_back(e);
  }
  const char* domains[4] = {"anterior", "posterior", "anterior_guarded", "posterior_guarded"};
  int eid = 0;
  for (int k = 0; k < 4; ++k) {
    if (elements_of[k].empty()) continue;
    os << "    <Elements type=\"" << (quadratic ? "tet10" : "tet4") << "\" name=\"" << domains[k]
       << "\">\n";
    for (int e : elements_of[k]) {
      // VTK and FEBio order the tet10 nodes alike: corners, then edges 12, 23, 31, 14, 24, 34.
      os << "      <elem id=\"" << ++eid << "\">";
      for (int a = 0; a < npe; ++a) os << (a ? "," : "") << nid(mesh.T(e, a));
      os << "</elem>\n";
    }
    os << "    </Elements>\n";
  }
  // Prescribed nodes: one node set each (one boundary condition per node and axis).
  for (const PrescribedNode& p : scene.prescribed)
    os << "    <NodeSet name=\"annulus_" << nid(p.node) << "\">" << nid(p.node) << "</NodeSet>\n";
  os << "    <NodeSet name=\"mvtwin_order\">";
  for (int i = 0; i < n; ++i) os << (i ? "," : "") << nid(i);
  os << "</NodeSet>\n";
  for (int k = 0; k < 2; ++k)
    os << "    <NodeSet name=\"papillary_tip_" << k + 1 << "\">" << n + 1 + k << "</NodeSet>\n";
  // Surfaces: the pressure surface and each leaflet's two surfaces for contact.
  const char* facet_type = quadratic ? "tri6" : "tri3";
  auto facet = [&](int fid_, int a, int b, int c) {
    std::ostringstream f;
    f << "      <" << facet_type << " id=\"" << fid_ << "\">" << nid(a) << "," << nid(b) << ","
      << nid(c);
    if (quadratic) {
      f << "," << nid(mesh.mid_node(a, b)) << "," << nid(mesh.mid_node(b, c)) << ","
        << nid(mesh.mid_node(c, a));
    }
    f << "</" << facet_type << ">\n";
    return f.str();
  };
  os << "    <Surface name=\"ventricular\">\n";
  int fid = 0;
  for (const PressureFace& pf : scene.pressure_faces) os << facet(++fid, pf.a, pf.b, pf.c);
  os << "    </Surface>\n";
  const std::vector<RimFace> rims = rim_faces(scene);
  for (int k = 0; k < 2; ++k) {
    os << "    <Surface name=\"" << domains[k] << "_surfaces\">\n";
    fid = 0;
    for (Eigen::Index f = 0; f < m.surface_triangles.rows(); ++f) {
      const bool anterior = m.surface_st(m.surface_triangles(f, 0), 0) < 0.5;
      if (anterior != (k == 0)) continue;
      for (int layer : {0, m.options.layers}) {
        int a = m.node(m.surface_triangles(f, 0), layer),
            b = m.node(m.surface_triangles(f, 1), layer),
            c = m.node(m.surface_triangles(f, 2), layer);
        if (layer == 0) std::swap(b, c);  // outward: towards the atrium on the atrial surface
        os << facet(++fid, a, b, c);
      }
    }
    for (const RimFace& r : rims)
      if (r.leaflet == k) os << facet(++fid, r.a, r.b, r.c);
    os << "    </Surface>\n";
  }
  os << "    <SurfacePair name=\"leaflets\">\n      <primary>anterior_surfaces</primary>\n"
     << "      <secondary>posterior_surfaces</secondary>\n    </SurfacePair>\n";
  // Springs: chordae and clips, one discrete set each.
  struct Spring {
    std::string name;
    int a, b;        // FEBio node ids
    double scale;    // share of the force
    double initial;  // the curve's reference length, mm (chordae: the mean point's)
    double rest;     // rest length, mm
    const ChordaLaw* law;
    double k;
  };
  std::vector<Spring> springs;
  auto middle = [&](const std::vector<int>& nodes) {
    std::vector<int> mid;
    const size_t s = nodes.size();
    if (s % 2) {
      mid.push_back(nodes[s / 2]);
    } else {
      mid.push_back(nodes[s / 2 - 1]);
      mid.push_back(nodes[s / 2]);
    }
    return mid;
  };
  for (size_t c = 0; c < scene.chordae.size(); ++c) {
    const SceneChorda& ch = scene.chordae[c];
    const auto parts = febio_chorda_springs(scene, static_cast<int>(c));
    for (size_t j = 0; j < parts.size(); ++j) {
      const FebioChordaSpring& sp = parts[j];
      springs.push_back({"chorda_" + std::to_string(c + 1) + "_" + std::to_string(j + 1),
                         nid(sp.node), n + 1 + ch.tip, sp.scale, sp.mean_length, sp.rest, &ch.law,
                         0.0});
    }
  }
  for (size_t c = 0; c < scene.springs.size(); ++c) {
    const SceneSpring& sp = scene.springs[c];
    const int a = middle(sp.a).front(), b = middle(sp.b).front();
    const double initial = (mesh.V.row(a) - mesh.V.row(b)).norm();
    springs.push_back({"clip_" + std::to_string(c + 1), nid(a), nid(b), 1.0, initial,
                       sp.rest_length, nullptr, sp.stiffness});
  }
  for (const Spring& s : springs)
    os << "    <DiscreteSet name=\"" << s.name << "\">\n      <delem>" << s.a << "," << s.b
       << "</delem>\n    </DiscreteSet>\n";
  os << "  </Mesh>\n";

  os << "  <MeshDomains>\n";
  for (int k = 0; k < 4; ++k) {
    if (elements_of[k].empty()) continue;
    os << "    <SolidDomain name=\"" << domains[k] << "\" mat=\""
       << (k < 2 ? names[k] : guarded_names[k - 2]) << "\"/>\n";
  }
  os << "  </MeshDomains>\n";

  // Per-element material axes: a = fibre.
  os << "  <MeshData>\n";
  for (int k = 0; k < 2; ++k) {
    os << "    <ElementData type=\"mat_axis\" elem_set=\"" << domains[k] << "\">\n";
    int lid = 0;
    for (int e : elements_of[k]) {
      const Eigen::Vector3d a = mesh.fibre.row(e).transpose().normalized();
      os << "      <elem lid=\"" << ++lid << "\"><a>" << vec(a) << "</a><d>" << vec(orthogonal(a))
         << "</d></elem>\n";
    }
    os << "    </ElementData>\n";
  }
  os << "  </MeshData>\n";

  // Prescribed motion: displacement curves per node and axis.
  const char* axes[3] = {"x", "y", "z"};
  os << "  <Boundary>\n";
  {
    std::vector<Eigen::VectorXd> positions;
    for (int k = 0; k < samples; ++k) {
      Eigen::VectorXd x = Eigen::VectorXd::Zero(3 * n);
      scene.prescribed_positions(sample_time(k), &x);
      positions.push_back(x);
    }
    for (const PrescribedNode& p : scene.prescribed) {
      for (int d = 0; d < 3; ++d) {
        std::vector<std::pair<double, double>> pts;
        for (int k = 0; k < samples; ++k)
          pts.emplace_back(sample_time(k), positions[k][3 * p.node + d] - mesh.V(p.node, d));
        const int id =
            add_curve("annulus_" + std::to_string(nid(p.node)) + "_" + axes[d], pts, "CONSTANT");
        os << "    <bc name=\"annulus_" << nid(p.node) << "_" << axes[d] << "\" node_set=\"annulus_"
           << nid(p.node) << "\" type=\"prescribed displacement\">\n      <dof>" << axes[d]
           << "</dof>\n      <value lc=\"" << id << "\">1</value>\n      <relative>0</relative>\n"
           << "    </bc>\n";
      }
    }
    for (int tip = 0; tip < 2; ++tip) {
      for (int d = 0; d < 3; ++d) {
        std::vector<std::pair<double, double>> pts;
        for (int k = 0; k < samples; ++k)
          pts.emplace_back(sample_time(k), scene.papillary_tip(tip, sample_time(k))[d] -
                                               scene.papillary_tip(tip, 0.0)[d]);
        const int id =
            add_curve("papillary_tip_" + std::to_string(tip + 1) + "_" + axes[d], pts, "CONSTANT");
        os << "    <bc name=\"papillary_tip_" << tip + 1 << "_" << axes[d]
           << "\" node_set=\"papillary_tip_" << tip + 1
           << "\" type=\"prescribed displacement\">\n      <dof>" << axes[d]
           << "</dof>\n      <value lc=\"" << id << "\">1</value>\n      <relative>0</relative>\n"
           << "    </bc>\n";
      }
    }
  }
  os << "  </Boundary>\n";

  // Pressure with the smoothstep profile (curve of the fraction of the peak).
  {
    std::vector<std::pair<double, double>> pts;
    for (int k = 0; k < samples; ++k)
      pts.emplace_back(sample_time(k),
                       scene.peak_pressure_mpa > 0
                           ? scene.pressure(sample_time(k)) / scene.peak_pressure_mpa
                           : 0.0);
    const int id = add_curve("pressure_profile", pts, "CONSTANT");
    os << "  <Loads>\n    <surface_load name=\"pressure\" surface=\"ventricular\" "
          "type=\"pressure\">\n"
       << "      <pressure lc=\"" << id << "\">" << num(scene.peak_pressure_mpa) << "</pressure>\n"
       << "      <symmetric_stiffness>1</symmetric_stiffness>\n      <linear>0</linear>\n"
       << "      <shell_bottom>0</shell_bottom>\n    </surface_load>\n  </Loads>\n";
  }

  if (opt.contact.enabled) {
    const FebioContactPotential cp = febio_contact_potential(
        opt.contact, opt.contact.stiffness_per_area(scene.peak_pressure_mpa),
        scene.peak_pressure_mpa);
    os << "  <Contact>\n    <!-- gap at peak pressure between flat leaflets: "
       << num(cp.gap_at_peak) << " mm (mvtwin: " << num(cp.mvtwin_gap_at_peak)
       << " mm) -->\n    <contact name=\"leaflets\" surface_pair=\"leaflets\" "
          "type=\"contact potential\">\n"
       << "      <kc>" << num(cp.kc) << "</kc>\n      <p>" << num(cp.p) << "</p>\n      <R_in>"
       << num(cp.r_in) << "</R_in>\n      <R_out>" << num(cp.r_out) << "</R_out>\n      <R0_min>"
       << num(cp.r0_min) << "</R0_min>\n      <w_tol>0</w_tol>\n    </contact>\n  </Contact>\n";
  }

  // Discrete springs: force against elongation from the reference length.
  os << "  <Discrete>\n";
  for (size_t s = 0; s < springs.size(); ++s) {
    const Spring& sp = springs[s];
    const auto pts = febio_spring_curve(sp.initial, sp.rest, sp.law, sp.k);
    os << "    <discrete_material id=\"" << s + 1 << "\" name=\"" << sp.name
       << "\" type=\"nonlinear spring\">\n      <scale>" << num(sp.scale)
       << "</scale>\n      <measure>elongation</measure>\n      <force type=\"point\">\n"
       << "        <interpolate>linear</interpolate>\n        <extend>extrapolate</extend>\n"
       << "        <points>\n";
    for (const auto& [x, f] : pts) os << "          <pt>" << num(x) << "," << num(f) << "</pt>\n";
    os << "        </points>\n      </force>\n    </discrete_material>\n";
  }
  for (size_t s = 0; s < springs.size(); ++s)
    os << "    <discrete dmat=\"" << s + 1 << "\" discrete_set=\"" << springs[s].name << "\"/>\n";
  os << "  </Discrete>\n";

  if (hold_s > 0) {
    // The load held (the curves extend constant) while the Maxwell branch relaxes.
    os << "  <Step>\n    <step name=\"relax\">\n";
    control("      ", kFebioRelaxSteps, hold_s / kFebioRelaxSteps, false);
    os << "    </step>\n  </Step>\n";
  }
  os << "  <LoadData>\n" << lc.str() << "  </LoadData>\n";
  // The node positions in mvtwin's node order at every converged step, as text: the closed
  // valve compares with mvtwin's without a reader for FEBio's binary plot file.
  os << "  <Output>\n    <logfile>\n      <node_data data=\"x;y;z\" delim=\" \" "
     << "node_set=\"mvtwin_order\" file=\"" << kFebioNodeLog << "\"/>\n    </logfile>\n"
     << "    <plotfile type=\"febio\">\n      <var type=\"displacement\"/>\n"
     << "      <var type=\"stress\"/>\n      <var type=\"contact gap\"/>\n"
     << "      <var type=\"contact pressure\"/>\n    </plotfile>\n  </Output>\n";
  os << "</febio_spec>\n";

  write_atomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream f(tmp);
    f << os.str();
    if (!f) throw Error(path.string() + ": cannot write");
  });
}

}  // namespace mvtwin::forward
