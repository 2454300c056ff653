#include "mvtwin/forward/closure_scene.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <tuple>

#include "mvtwin/core/error.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::forward {
namespace {

double smoothstep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

/// The cross-section of the leaflet at surface node i: the node on every layer and the mid-edge
/// nodes between layers (quadratic meshes).
std::vector<int> cross_section(const ValveModel& m, int i) {
  std::vector<int> nodes;
  for (int l = 0; l <= m.options.layers; ++l) {
    nodes.push_back(m.node(i, l));
    if (l > 0 && m.mesh.order == TetOrder::kQuadratic) {
      const int mid = m.mesh.mid_node(m.node(i, l - 1), m.node(i, l));
      if (mid >= 0) nodes.push_back(mid);
    }
  }
  return nodes;
}

/// Surface node nearest to grid site (s, t) in the unrolled plane.
int nearest_surface_node(const ValveModel& m, double s, double t) {
  s -= std::floor(s);
  int best = -1;
  double best_d = std::numeric_limits<double>::infinity();
  for (int i = 0; i < m.surface_nodes; ++i) {
    double ds = m.surface_st(i, 0) - s;
    ds -= std::round(ds);
    const double d = std::hypot(ds * m.perimeter, (m.surface_st(i, 1) - t) * 20.0);
    if (d < best_d) {
      best_d = d;
      best = i;
    }
  }
  return best;
}

/// The band of one leaflet a device grasps: surface nodes within half the width of the site
/// along the annulus (arc length in the unrolled plane) and within the insertion of the free
/// edge, each with its offset along the coaptation line (mm, in the line's direction) and its
/// distance from the free edge (mm).
struct Band {
  std::vector<int> nodes;
  std::vector<double> along, from_edge;
};

Band grasped_band(const ValveModel& m, double s_site, bool anterior, double width,
                  double insertion) {
  // Arc length of the site: the annulus columns' unrolled positions, interpolated.
  const int U = static_cast<int>(m.annulus_column.size());
  const double x = (s_site - std::floor(s_site)) * U;
  const int u0 = static_cast<int>(std::floor(x)) % U, u1 = (u0 + 1) % U;
  double xi0 = m.surface_plane(m.annulus_column[u0], 0),
         xi1 = m.surface_plane(m.annulus_column[u1], 0);
  if (xi1 < xi0) xi1 += m.perimeter;
  const double xi_site = xi0 + (x - std::floor(x)) * (xi1 - xi0);
  Band b;
  for (int i = 0; i < m.surface_nodes; ++i) {
    const double t = m.surface_st(i, 1);
    if ((m.surface_st(i, 0) < 0.5) != anterior || t < 0.05) continue;
    double d = m.surface_plane(i, 0) - xi_site;
    d -= m.perimeter * std::round(d / m.perimeter);
    const double depth = m.surface_plane(i, 1), from_edge = depth * (1.0 / t - 1.0);
    if (std::abs(d) > 0.5 * width || from_edge > insertion) continue;
    b.nodes.push_back(i);
    // Along the line: the anterior leaflet's arc runs with the line, the posterior's against it.
    b.along.push_back(anterior ? d : -d);
    b.from_edge.push_back(from_edge);
  }
  return b;
}

/// Elements of the corner mesh with a corner within `margin` (unrolled plane, mm) of a node of
/// `band` (surface nodes).
std::vector<int> elements_near(const ValveModel& m, const std::vector<int>& band, double margin) {
  std::vector<char> near(static_cast<size_t>(m.surface_nodes), 0);
  for (int i = 0; i < m.surface_nodes; ++i) {
    for (int b : band) {
      double dx = m.surface_plane(i, 0) - m.surface_plane(b, 0);
      dx -= m.perimeter * std::round(dx / m.perimeter);
      if (std::hypot(dx, m.surface_plane(i, 1) - m.surface_plane(b, 1)) <= margin) {
        near[static_cast<size_t>(i)] = 1;
        break;
      }
    }
  }
  std::vector<int> out;
  for (Eigen::Index e = 0; e < m.linear.T.rows(); ++e) {
    for (int k = 0; k < 4; ++k) {
      if (near[static_cast<size_t>(m.linear.T(e, k) % m.surface_nodes)]) {
        out.push_back(static_cast<int>(e));
        break;
      }
    }
  }
  return out;
}

}  // namespace

std::pair<double, double> clip_insertion_mm(const ValveSequence& seq, const ClipOptions& clip) {
  // The leaflets span the annulus chord between the sites (first closed frame) to their meeting
  // point, in proportion to their lengths (end-diastole); what is left of each inserts.
  const LeafletGrid& ed = *seq.frames[static_cast<size_t>(seq.end_diastole)].la_surface;
  const auto closed =
      resample_closed_curve(seq.frames[static_cast<size_t>(seq.first_closed)].annulus, 512);
  auto annulus_at = [&](double s) -> Eigen::Vector3d {
    return closed.row(static_cast<int>(std::lround((s - std::floor(s)) * 512)) % 512).transpose();
  };
  const double La = ed.radial_length_at(clip.anterior_s),
               Lp = ed.radial_length_at(clip.posterior_s);
  const double chord = (annulus_at(clip.anterior_s) - annulus_at(clip.posterior_s)).norm();
  const double excess = std::max(0.0, La + Lp - chord);
  auto insertion = [&](double L, double given) {
    return std::min(clip.arm_length_mm, given > 0 ? given : L * excess / (La + Lp));
  };
  return {insertion(La, clip.anterior_insertion_mm), insertion(Lp, clip.posterior_insertion_mm)};
}

void add_device_clip(const ValveSequence& seq, const ClosureOptions& opt, int index,
                     ClosureScene* sc) {
  const ClipOptions& clip = opt.clips[static_cast<size_t>(index)];
  const ValveModel& model = sc->model;
  ClipGrasp g;
  g.device = clip.device.empty() ? "device" : clip.device;
  std::tie(g.anterior_insertion_mm, g.posterior_insertion_mm) = clip_insertion_mm(seq, clip);
  const Band a = grasped_band(model, clip.anterior_s, true, clip.width_mm, g.anterior_insertion_mm);
  const Band p =
      grasped_band(model, clip.posterior_s, false, clip.width_mm, g.posterior_insertion_mm);
  g.anterior_nodes = static_cast<int>(a.nodes.size());
  g.posterior_nodes = static_cast<int>(p.nodes.size());
  g.anterior_band = a.nodes;
  g.posterior_band = p.nodes;
  {
    std::vector<int> both = a.nodes;
    both.insert(both.end(), p.nodes.begin(), p.nodes.end());
    g.region_elements = elements_near(model, both, kGraspStressMarginMm);
  }
  // Its place on the coaptation line (anterior s / 0.5, posterior (1 - s) / 0.5).
  g.line_begin = 1.0;
  g.line_end = 0.0;
  for (int i : a.nodes) {
    g.line_begin = std::min(g.line_begin, 2.0 * model.surface_st(i, 0));
    g.line_end = std::max(g.line_end, 2.0 * model.surface_st(i, 0));
  }
  for (int i : p.nodes) {
    g.line_begin = std::min(g.line_begin, 2.0 * (1.0 - model.surface_st(i, 0)));
    g.line_end = std::max(g.line_end, 2.0 * (1.0 - model.surface_st(i, 0)));
  }
  if (a.nodes.empty() || p.nodes.empty()) {
    throw Error(
        "clip " + std::to_string(index + 1) + " (" + g.device + "): grasps no tissue of the " +
        (a.nodes.empty() ? "anterior" : "posterior") + " leaflet (insertion " +
        std::to_string(a.nodes.empty() ? g.anterior_insertion_mm : g.posterior_insertion_mm) +
        " mm): the leaflets are too short at the site to reach the device");
  }
  // Ties: each grasped cross-section to the two nearest of the other band (offset along the line,
  // distance from the free edge), at the distance they have when both bands lie flat face to
  // face, spacer (at least the contact law's reach, where it stops pushing) between their atrial
  // surfaces: the ties do not hold the surfaces where the contact law pushes them apart.
  const double gap = 0.5 * (opt.model.al_thickness_mm + opt.model.pl_thickness_mm) +
                     std::max(clip.spacer_mm, opt.contact.alarm_mm);
  std::set<std::pair<int, int>> pairs;
  auto tie = [&](const Band& from, const Band& to, bool from_anterior) {
    for (size_t i = 0; i < from.nodes.size(); ++i) {
      std::vector<std::pair<double, size_t>> d;
      for (size_t j = 0; j < to.nodes.size(); ++j) {
        d.emplace_back(std::hypot(from.along[i] - to.along[j], from.from_edge[i] - to.from_edge[j]),
                       j);
      }
      std::sort(d.begin(), d.end());
      for (size_t k = 0; k < std::min<size_t>(2, d.size()); ++k) {
        const int ai = from_anterior ? from.nodes[i] : to.nodes[d[k].second];
        const int pi = from_anterior ? to.nodes[d[k].second] : from.nodes[i];
        if (!pairs.insert({ai, pi}).second) continue;
        SceneSpring sp;
        sp.a = cross_section(model, ai);
        sp.b = cross_section(model, pi);
        sp.stiffness = clip.stiffness_n_per_mm;
        sp.rest_length = std::hypot(gap, d[k].first);
        sp.clip = index;
        sp.bilateral = true;
        sc->springs.push_back(sp);
      }
    }
  };
  tie(a, p, true);
  tie(p, a, false);
  g.ties = static_cast<int>(pairs.size());
  sc->grasps.push_back(g);
}

namespace {}  // namespace

double ClosureScene::observed_time(double tau) const {
  // After the closure (settling) the boundary stays where the closed frame has it.
  return sequence_.frames[sequence_.end_diastole].time_s + std::min(tau, duration_) / stretch_;
}

double ClosureScene::pressure(double tau) const {
  return peak_pressure_mpa * smoothstep(duration_ > 0 ? tau / duration_ : 1.0);
}

int ClosureScene::clamp_frame(int i) const { return std::clamp(i, 0, sequence_.num_frames() - 1); }

// Catmull-Rom weights over frames (f-1, f, f+1, f+2) at observed time t: the prescribed motion
// is C1 in time between the image frames.
void ClosureScene::weights(double t, int* f, Eigen::Vector4d* w) const {
  const int n = sequence_.num_frames();
  int i = sequence_.end_diastole;
  while (i + 1 < n - 1 && sequence_.frames[i + 1].time_s <= t) ++i;
  while (i > 0 && sequence_.frames[i].time_s > t) --i;
  const double t0 = sequence_.frames[i].time_s,
               t1 = sequence_.frames[std::min(i + 1, n - 1)].time_s;
  const double x = t1 > t0 ? std::clamp((t - t0) / (t1 - t0), 0.0, 1.0) : 0.0;
  const double x2 = x * x, x3 = x2 * x;
  *f = i;
  *w << -0.5 * x3 + x2 - 0.5 * x, 1.5 * x3 - 2.5 * x2 + 1.0, -1.5 * x3 + 2.0 * x2 + 0.5 * x,
      0.5 * x3 - 0.5 * x2;
}

Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> ClosureScene::annulus(double tau) const {
  if (!annulus_motion_) return annulus_[sequence_.end_diastole];
  int f;
  Eigen::Vector4d w;
  weights(observed_time(tau), &f, &w);
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> a = w[0] * annulus_[clamp_frame(f - 1)];
  for (int k = 1; k < 4; ++k) a += w[k] * annulus_[clamp_frame(f - 1 + k)];
  return a;
}

Eigen::Vector3d ClosureScene::landmark(Landmark l, double tau) const {
  const bool papillary =
      l == Landmark::kAnterolateralPapillaryTip || l == Landmark::kPosteromedialPapillaryTip;
  if ((papillary && !papillary_motion_) || (!papillary && !annulus_motion_)) {
    return sequence_.frames[sequence_.end_diastole].landmark(l);
  }
  int f;
  Eigen::Vector4d w;
  weights(observed_time(tau), &f, &w);
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int k = 0; k < 4; ++k) {
    const ValveFrame& fr = sequence_.frames[clamp_frame(f - 1 + k)];
    // An unobserved neighbour falls back to the nearest observed frame of the window.
    p += w[k] * (fr.observed(l) ? fr.landmark(l)
                                : sequence_.frames[clamp_frame(f + (k >= 2))].landmark(l));
  }
  return p;
}

bool ClosureScene::observed_at_end_diastole(Landmark l) const {
  return sequence_.frames[sequence_.end_diastole].observed(l);
}

Eigen::Vector3d ClosureScene::papillary_tip(int k, double tau) const {
  return landmark(
      k == 0 ? Landmark::kAnterolateralPapillaryTip : Landmark::kPosteromedialPapillaryTip, tau);
}

void ClosureScene::prescribed_positions(double tau, Eigen::VectorXd* x) const {
  const auto a = annulus(tau);
  for (const PrescribedNode& p : prescribed) {
    const Eigen::Vector3d d =
        0.5 *
        ((a.row(p.ua) - annulus_ed_.row(p.ua)) + (a.row(p.ub) - annulus_ed_.row(p.ub))).transpose();
    x->segment<3>(3 * p.node) = model.mesh.V.row(p.node).transpose() + d;
  }
}

ClosureScene make_closure_scene(const ValveSequence& seq, const ValveParameters& params,
                                const ClosureOptions& opt) {
  std::string err;
  if (!opt.is_valid(&err)) throw Error("closure options: " + err);
  if (seq.first_closed <= seq.end_diastole || seq.end_diastole < 0) {
    throw Error(
        "closure simulation: the sequence needs an end-diastolic frame before a first closed "
        "frame");
  }
  for (const ChordaeRupture& r : seq.ruptured_chordae) {
    if (!r.is_valid())
      throw Error("closure simulation: a chordae rupture must have 0 <= s_begin < s_end <= 1");
  }
  if (const std::string problem = seq.chordae_lengths_problem(); !problem.empty())
    throw Error("closure simulation: " + problem);
  ClosureScene sc;
  // A device's grasp refined (ModelOptions::refine_factor): each band and the stress region
  // around it (kGraspStressMarginMm), as deep as the leaflet inserts plus that margin.
  ModelOptions mo = opt.model;
  if (mo.refine_factor > 1) {
    for (const ClipOptions& clip : opt.clips) {
      if (!(clip.width_mm > 0)) continue;
      const auto [ia, ip] = clip_insertion_mm(seq, clip);
      const double hw = 0.5 * clip.width_mm + kGraspStressMarginMm;
      mo.refine_regions.push_back({clip.anterior_s, hw, ia + kGraspStressMarginMm});
      mo.refine_regions.push_back({clip.posterior_s, hw, ip + kGraspStressMarginMm});
    }
  }
  sc.model = build_valve_model(seq, mo);
  const ValveModel& model = sc.model;
  const SolidMesh& mesh = model.mesh;
  sc.leaflet_material = {
      TransverselyIsotropic::anterior_leaflet().scaled(params.al_modulus_scale),
      TransverselyIsotropic::posterior_leaflet().scaled(params.pl_modulus_scale)};
  sc.sequence_ = seq;
  sc.stretch_ = opt.stretch;
  sc.annulus_motion_ = opt.annulus_motion;
  sc.papillary_motion_ = opt.papillary_motion;
  sc.duration_ =
      opt.stretch * (seq.frames[seq.first_closed].time_s - seq.frames[seq.end_diastole].time_s);
  if (!(sc.duration_ > 0)) throw Error("closure simulation: the closure lasts no time");
  const int U = opt.model.ures, L = opt.model.layers;
  for (const ValveFrame& f : seq.frames) sc.annulus_.push_back(resample_closed_curve(f.annulus, U));
  sc.annulus_ed_ = sc.annulus(0.0);
  sc.peak_pressure_mpa = params.peak_pressure_mpa;

  // Chordae with their rest lengths and laws; the marginal chordae whose insertion site (k / n
  // of n evenly spaced ones) lies in a ruptured stretch of the anatomy are left out.
  // Where the anatomy gives the marginal chordae's lengths, their rest lengths start from those.
  int marginal_index = 0;
  for (const ModelChorda& c : model.chordae) {
    double base_length = c.ed_length;
    if (c.marginal) {
      const double site = static_cast<double>(marginal_index++) / opt.model.marginal_chordae;
      if (std::any_of(seq.ruptured_chordae.begin(), seq.ruptured_chordae.end(),
                      [site](const ChordaeRupture& r) { return r.contains(site); }))
        continue;
      if (!seq.marginal_chordae_lengths.empty()) base_length = seq.marginal_chorda_length_at(site);
    }
    SceneChorda ch;
    ch.nodes = c.nodes;
    ch.tip = c.papillary;
    ch.rest_length = base_length * params.restlength_factor[static_cast<int>(c.group)];
    ch.law = c.marginal ? ChordaLaw::marginal().stiffness_scaled(params.marginal_stiffness_scale)
                        : ChordaLaw::basal().stiffness_scaled(params.basal_stiffness_scale);
    ch.group = c.group;
    ch.marginal = c.marginal;
    sc.chordae.push_back(ch);
  }

  // Clips: the paper's spring between the cross-sections at the two sites, held at the distance
  // of the two cross-sections' mid-planes when their atrial surfaces are the contact distance
  // apart; or a device grasping a band of each leaflet (add_device_clip).
  for (size_t c = 0; c < opt.clips.size(); ++c) {
    const ClipOptions& clip = opt.clips[c];
    if (clip.width_mm > 0) {
      add_device_clip(seq, opt, static_cast<int>(c), &sc);
      continue;
    }
    SceneSpring sp;
    const int na = nearest_surface_node(model, clip.anterior_s, clip.anterior_t),
              nb = nearest_surface_node(model, clip.posterior_s, clip.posterior_t);
    sp.a = cross_section(model, na);
    sp.b = cross_section(model, nb);
    sp.stiffness = clip.stiffness_n_per_mm;
    sp.rest_length =
        0.5 * (opt.model.al_thickness_mm + opt.model.pl_thickness_mm) + opt.contact.contact_mm;
    sp.clip = static_cast<int>(c);
    sc.springs.push_back(sp);
    ClipGrasp g;
    g.device = clip.device.empty() ? "spring" : clip.device;
    g.anterior_nodes = g.posterior_nodes = g.ties = 1;
    g.anterior_band = {na};
    g.posterior_band = {nb};
    g.region_elements = elements_near(model, {na, nb}, kGraspStressMarginMm);
    sc.grasps.push_back(g);
  }

  // Prescribed nodes follow the displacement of their annulus grid points.
  std::map<int, int> corner_u;  // annulus corner node -> u
  for (int l = 0; l <= L; ++l) {
    for (int u = 0; u < U; ++u) corner_u[model.node(model.annulus_column[u], l)] = u;
  }
  std::map<int, std::pair<int, int>> mid_of_annulus;  // prescribed mid-edge node -> its edge
  for (const auto& [edge, mid] : mesh.mid_edge) {
    if (corner_u.count(edge.first) && corner_u.count(edge.second)) mid_of_annulus[mid] = edge;
  }
  for (int node : model.annulus_nodes) {
    if (corner_u.count(node)) {
      sc.prescribed.push_back({node, corner_u.at(node), corner_u.at(node)});
    } else {
      const auto& edge = mid_of_annulus.at(node);
      sc.prescribed.push_back({node, corner_u.at(edge.first), corner_u.at(edge.second)});
    }
  }

  for (const Eigen::Vector3i& f : model.ventricular_faces) {
    PressureFace pf{f[0], f[1], f[2], {f[0], f[1], f[2]}};
    if (mesh.order == TetOrder::kQuadratic) {
      pf.load[0] = mesh.mid_node(f[0], f[1]);
      pf.load[1] = mesh.mid_node(f[1], f[2]);
      pf.load[2] = mesh.mid_node(f[0], f[2]);
    }
    sc.pressure_faces.push_back(pf);
  }
  return sc;
}

}  // namespace mvtwin::forward
