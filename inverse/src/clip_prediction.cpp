#include "mvtwin/inverse/clip_prediction.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

#include "mvtwin/core/error.h"
#include "mvtwin/forward/clip_device.h"
#include "mvtwin/forward/closure_scene.h"
#include "parallel_indices.h"

namespace mvtwin::inverse {

forward::ClipOptions clip_options(const ClipSite& s) {
  forward::ClipOptions c;
  c.anterior_s = 0.5 * s.position;
  c.posterior_s = 1.0 - 0.5 * s.position;
  c.anterior_t = c.posterior_t = s.depth;
  if (s.device != "spring") {
    const forward::ClipDevice& d = forward::clip_device(s.device);
    c.width_mm = d.width_mm;
    c.arm_length_mm = d.arm_length_mm;
    c.spacer_mm = d.spacer_mm;
    c.anterior_insertion_mm = c.posterior_insertion_mm = s.insertion_mm;
    c.device = d.name;
    c.anterior_t = c.posterior_t = 1.0;
  } else {
    c.device = "spring";
  }
  return c;
}

std::string describe_sites(const std::vector<ClipSite>& sites) {
  std::string out;
  for (const ClipSite& s : sites) {
    char b[64];
    std::snprintf(b, sizeof b, "%s at %.2f", s.device.c_str(), s.position);
    out += (out.empty() ? "" : "; ") + std::string(b);
  }
  return out.empty() ? "no clip" : out;
}

std::vector<ClipSite> parse_clip_sites(const std::string& text, const std::string& device) {
  if (device != "spring") forward::clip_device(device);  // refuses an unknown name
  std::vector<ClipSite> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ';')) {
    if (item.find_first_not_of(" \t") == std::string::npos) continue;
    ClipSite s;
    s.device = device == "spring" ? device : forward::clip_device(device).name;
    std::stringstream is(item);
    std::string a, b;
    std::getline(is, a, ',');
    std::getline(is, b, ',');
    try {
      size_t used = 0;
      s.position = std::stod(a, &used);
      if (a.find_first_not_of(" \t", used) != std::string::npos) throw std::invalid_argument(a);
      if (!b.empty()) {
        s.depth = std::stod(b, &used);
        if (b.find_first_not_of(" \t", used) != std::string::npos) throw std::invalid_argument(b);
      }
    } catch (const std::exception&) {
      throw Error("clip sites: cannot read '" + item + "' (expected position[,depth], e.g. 0.5,1)");
    }
    if (!(s.position > 0 && s.position < 1)) {
      throw Error("clip sites: position " + a + " must be strictly between 0 and 1 (commissures)");
    }
    if (!(s.depth > 0.3 && s.depth <= 1)) {
      throw Error("clip sites: depth " + b + " must be in (0.3, 1] (1 = free edge)");
    }
    out.push_back(s);
  }
  if (out.empty()) throw Error("clip sites: none given ('" + text + "')");
  return out;
}

ClosureQuality closure_quality(const forward::ClosureResult& r) {
  ClosureQuality q;
  q.converged = r.summary.converged();
  q.reason = r.summary.reason;
  if (r.orifice) q.orifice = *r.orifice;
  q.clip_gap_mm = r.clip_gap_end_mm;
  q.clip_grasps = r.clip_grasps;
  q.element_stress_mpa = r.element_stress_mpa;
  q.chorda_tension_n = r.chorda_tension_n;
  q.chorda_marginal = r.chorda_marginal;
  if (!r.samples.empty()) q.closed_surface = r.samples.back().la_surface;
  return q;
}

namespace {

/// What decides a clipped valve's simulation: each clip's sites, width, spacer and stiffness, and
/// the insertions it grasps. An arm caps the insertion and is used for nothing else, so two
/// devices whose arms both hold all the tissue the leaflets insert grasp the same bands (NT and
/// XT, NTW and XTW wherever the leaflets insert less than 9 mm): equal keys, the same simulation
/// to the bit. A key that cannot be made (the insertion's geometry refused) is unique, so that the
/// simulation itself reports why.
std::string grasp_key(const ValveSequence& seq, const std::vector<ClipSite>& sites, size_t i) {
  std::ostringstream k;
  k.precision(17);
  try {
    for (const ClipSite& s : sites) {
      forward::ClipOptions c = clip_options(s);
      if (c.width_mm > 0)
        std::tie(c.anterior_insertion_mm, c.posterior_insertion_mm) =
            forward::clip_insertion_mm(seq, c);
      k << c.anterior_s << ' ' << c.anterior_t << ' ' << c.posterior_s << ' ' << c.posterior_t
        << ' ' << c.stiffness_n_per_mm << ' ' << c.width_mm << ' ' << c.spacer_mm << ' '
        << c.anterior_insertion_mm << ' ' << c.posterior_insertion_mm << ';';
    }
  } catch (const std::exception&) {
    return "#" + std::to_string(i);
  }
  return k.str();
}

}  // namespace

std::vector<size_t> alike_clips(const ValveSequence& seq,
                                const std::vector<std::vector<ClipSite>>& sites) {
  std::map<std::string, size_t> seen;
  std::vector<size_t> first(sites.size());
  for (size_t i = 0; i < sites.size(); ++i)
    first[i] = seen.emplace(grasp_key(seq, sites[i], i), i).first->second;
  return first;
}

std::vector<ClipScenario> simulate_clips(const Patient& patient, const ValveParameters& par,
                                         const forward::ClosureOptions& options,
                                         const std::vector<std::vector<ClipSite>>& candidates,
                                         int jobs) {
  std::vector<ClipScenario> out(candidates.size());
  // A valve that two candidates clip alike is simulated once (grasp_key).
  const std::vector<size_t> first = alike_clips(patient.sequence, candidates);
  std::vector<size_t> unique;
  for (size_t i = 0; i < candidates.size(); ++i)
    if (first[i] == i) unique.push_back(i);
  parallel_indices(unique.size(), jobs, [&](size_t u) {
    const size_t i = unique[u];
    ClipScenario& sc = out[i];
    sc.sites = candidates[i];
    forward::ClosureOptions o = options;
    o.progress = nullptr;
    o.clips.clear();
    for (const ClipSite& s : sc.sites) o.clips.push_back(clip_options(s));
    try {
      sc.quality = closure_quality(forward::simulate_closure(patient.sequence, par, o));
    } catch (const std::exception& e) {
      sc.quality.converged = false;
      sc.quality.reason = e.what();
    }
  });
  for (size_t i = 0; i < candidates.size(); ++i) {
    if (first[i] == i) continue;
    ClipScenario& sc = out[i];
    sc.sites = candidates[i];
    sc.quality = out[first[i]].quality;
    for (size_t c = 0; c < sc.quality.clip_grasps.size() && c < sc.sites.size(); ++c)
      sc.quality.clip_grasps[c].device = clip_options(sc.sites[c]).device;
  }
  return out;
}

void open_clips(const Patient& patient, const ValveParameters& par,
                const forward::ClosureOptions& options, const forward::DiastoleOptions& diastole,
                size_t count, int jobs, std::vector<ClipScenario>* scenarios) {
  const size_t n = std::min(count, scenarios->size());
  std::vector<std::vector<ClipSite>> sites;
  for (size_t i = 0; i < n; ++i) sites.push_back((*scenarios)[i].sites);
  const std::vector<size_t> first = alike_clips(patient.sequence, sites);
  std::vector<size_t> unique;
  for (size_t i = 0; i < n; ++i)
    if (first[i] == i) unique.push_back(i);
  parallel_indices(unique.size(), jobs, [&](size_t u) {
    ClipScenario& sc = (*scenarios)[unique[u]];
    forward::ClosureOptions o = options;
    o.progress = nullptr;
    o.clips.clear();
    for (const ClipSite& s : sc.sites) o.clips.push_back(clip_options(s));
    ClipOpening& op = sc.opening;
    op.computed = true;
    try {
      const forward::DiastolicOpening d =
          forward::simulate_diastole(patient.sequence, par, o, diastole);
      op.converged = d.converged;
      op.reason = d.reason;
      op.mva_cm2 = d.mva_cm2;
      op.gradient_mmhg = d.gradient_mmhg;
      op.stenosis = d.stenosis;
      op.openings_cm2 = d.openings_cm2;
      op.frame = d.frame;
      op.fallback = d.fallback;
      if (!d.result.samples.empty()) op.open_surface = d.result.samples.back().la_surface;
    } catch (const std::exception& e) {
      op.converged = false;
      op.reason = e.what();
    }
  });
  for (size_t i = 0; i < n; ++i)
    if (first[i] != i) (*scenarios)[i].opening = (*scenarios)[first[i]].opening;
}

std::vector<std::vector<ClipSite>> clip_candidates(bool pairs,
                                                   const std::vector<std::string>& devices) {
  std::vector<double> pos;
  for (int k = 2; k <= 8; ++k) pos.push_back(0.1 * k);
  std::vector<std::vector<ClipSite>> out;
  for (const std::string& d : devices) {
    for (double p : pos) out.push_back({ClipSite{p, 1.0, d}});
  }
  if (pairs) {
    for (const std::string& d : devices) {
      for (size_t i = 0; i < pos.size(); ++i)
        for (size_t j = i + 1; j < pos.size(); ++j)
          if (pos[j] - pos[i] >= 0.2 - 1e-9)
            out.push_back({ClipSite{pos[i], 1.0, d}, ClipSite{pos[j], 1.0, d}});
    }
  }
  return out;
}

std::vector<std::vector<ClipSite>> pairs_around(const std::vector<std::vector<ClipSite>>& singles) {
  std::vector<std::vector<ClipSite>> out;
  std::set<std::tuple<std::string, long, long>> seen;
  for (const auto& one : singles) {
    if (one.size() != 1) continue;
    const ClipSite& a = one.front();
    for (int k = 2; k <= 8; ++k) {
      const double p = 0.1 * k;
      if (std::abs(p - a.position) < 0.2 - 1e-9) continue;
      ClipSite b = a;
      b.position = p;
      const ClipSite& lo = a.position < p ? a : b;
      const ClipSite& hi = a.position < p ? b : a;
      const auto key =
          std::make_tuple(a.device, std::lround(100 * lo.position), std::lround(100 * hi.position));
      if (!seen.insert(key).second) continue;
      out.push_back({lo, hi});
    }
  }
  return out;
}

GraspLoads grasp_loads(const ClosureQuality& before, const ClosureQuality& after) {
  GraspLoads g;
  auto quantile = [](const ClosureQuality& q, const std::vector<int>& elements, double at = 0.95) {
    forward::ClosureResult r;
    r.element_stress_mpa = q.element_stress_mpa;
    return forward::stress_quantile_kpa(r, elements, at);
  };
  for (const forward::ClipGrasp& c : after.clip_grasps) {
    g.stress_p95_after_kpa = std::max(g.stress_p95_after_kpa, quantile(after, c.region_elements));
    g.stress_max_after_kpa =
        std::max(g.stress_max_after_kpa, quantile(after, c.region_elements, 1.0));
    g.stress_p95_before_kpa =
        std::max(g.stress_p95_before_kpa, quantile(before, c.region_elements));
  }
  auto largest = [](const ClosureQuality& q) {
    double m = 0;
    for (size_t c = 0; c < q.chorda_tension_n.size(); ++c)
      if (q.chorda_marginal[c]) m = std::max(m, q.chorda_tension_n[c]);
    return m;
  };
  g.marginal_tension_before_n = largest(before);
  g.marginal_tension_after_n = largest(after);
  return g;
}

ClipFlags clip_flags(const std::vector<forward::ClipGrasp>& grasps) {
  ClipFlags f;
  bool any = false;
  for (const forward::ClipGrasp& g : grasps) {
    if (g.line_end <= g.line_begin) continue;  // the paper's spring: no arm
    const double m = std::min(g.anterior_insertion_mm, g.posterior_insertion_mm);
    f.min_insertion_mm = any ? std::min(f.min_insertion_mm, m) : m;
    any = true;
  }
  f.detachment_risk = any && f.min_insertion_mm < kMinInsertionMm;
  return f;
}

EverestCriteria everest_criteria(const RegurgitantOrifice& o) {
  EverestCriteria e;
  e.coaptation_length_mm = o.coaptation_length_mm;
  e.coaptation_depth_mm = o.coaptation_depth_mm;
  if (!o.openings.empty()) {
    e.flail_gap_mm = o.openings.front().max_gap_mm;
    e.flail_width_mm = o.openings.front().length_mm;
  }
  e.coaptation_length_ok = e.coaptation_length_mm >= 2.0;
  e.coaptation_depth_ok = std::isfinite(e.coaptation_depth_mm) && e.coaptation_depth_mm < 11.0;
  e.flail_gap_ok = e.flail_gap_mm < 10.0;
  e.flail_width_ok = e.flail_width_mm < 15.0;
  return e;
}

void rank_by_residual_orifice(std::vector<ClipScenario>* s) {
  std::stable_sort(s->begin(), s->end(), [](const ClipScenario& a, const ClipScenario& b) {
    if (a.quality.converged != b.quality.converged) return a.quality.converged;
    return a.quality.orifice.eroa_mm2 < b.quality.orifice.eroa_mm2;
  });
}

}  // namespace mvtwin::inverse

namespace mvtwin::inverse {

Eigen::VectorXd clip_outcomes(const ClipScenario& s, const ClosureQuality& before) {
  constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  Eigen::VectorXd v = Eigen::VectorXd::Constant(kClipOutcomes, nan);
  if (s.quality.converged) {
    v[0] = s.quality.orifice.eroa_mm2;
    if (before.converged || s.sites.empty())
      v[3] = grasp_loads(before, s.quality).stress_p95_after_kpa;
  }
  if (s.opening.computed && s.opening.converged) {
    v[1] = s.opening.mva_cm2;
    v[2] = s.opening.gradient_mmhg;
  }
  return v;
}

forward::ClosureOptions refined_options(const forward::ClosureOptions& options, double factor) {
  if (!(factor >= 1.0) || !std::isfinite(factor))
    throw Error("refined_options: the refinement factor must be at least 1 (got " +
                std::to_string(factor) + ")");
  forward::ClosureOptions r = options;
  auto finer = [&](int n) {
    const int m = static_cast<int>(std::ceil(n * factor - 1e-9));
    return m + (m % 2);
  };
  r.model.ures = finer(options.model.ures);
  r.model.vres = finer(options.model.vres);
  return r;
}

SigmaPoints propagate_clip_uncertainty(const Patient& patient, const CalibrationPosterior& post,
                                       const forward::ClosureOptions& options,
                                       const forward::DiastoleOptions& diastole,
                                       const ClosureQuality& before_at_center, size_t count,
                                       int jobs, std::vector<ClipScenario>* scenarios,
                                       const MeshCheck& mesh) {
  SigmaPoints sp;
  if (!post.usable) return sp;
  // Before any simulation, so that a bad factor is refused first.
  const forward::ClosureOptions refined =
      mesh.enabled ? refined_options(options, mesh.factor) : options;
  sp = sigma_points(post.fitted, post.covariance, post.lower, post.upper);
  const size_t n = std::min(count, scenarios->size());
  const size_t np = sp.points.size();
  // Every scenario (and the valve without a clip, first) at every sigma point, at once.
  // A scenario without a clip is that valve itself (opened in diastole when it is asked for).
  // Scenarios that clip the valve alike (grasp_key) share a column.
  std::vector<std::vector<ClipSite>> sites{{}};
  std::vector<size_t> column(n, 0);
  std::map<std::string, size_t> column_of;
  bool open_before = false;
  for (size_t i = 0; i < n; ++i) {
    if ((*scenarios)[i].sites.empty()) {
      open_before = true;
      continue;
    }
    const auto [it, fresh] =
        column_of.emplace(grasp_key(patient.sequence, (*scenarios)[i].sites, i), sites.size());
    column[i] = it->second;
    if (fresh) sites.push_back((*scenarios)[i].sites);
  }
  // Rows 0..np-1: the sigma points; row np (with the mesh check): the fitted parameters on the
  // refined mesh.
  const size_t rows = np + (mesh.enabled ? 1 : 0);
  std::vector<ValveParameters> par(rows);
  for (size_t k = 0; k < np; ++k) par[k] = post.apply(sp.points[k]);
  if (mesh.enabled) par[np] = post.apply(post.fitted);
  const size_t per = sites.size();
  std::vector<ClipScenario> flat(rows * per);
  auto run = [&](size_t i) {
    const size_t k = i / per, c = i % per;
    const forward::ClosureOptions& o = k < np ? options : refined;
    std::vector<ClipScenario> one = simulate_clips(patient, par[k], o, {sites[c]}, 1);
    if (c > 0 || open_before) open_clips(patient, par[k], o, diastole, 1, 1, &one);
    flat[i] = std::move(one.front());
  };
  parallel_indices(rows * per, jobs, run);
  // A sigma point where a simulation fails is tried again nearer the center
  // (halve_failed_points). Only columns that ran at the center count: an option whose own
  // closure failed has no SD to save, and retrying its column would redo every point for nothing.
  std::vector<char> center_ran(per, 0);
  center_ran[0] = before_at_center.converged;
  for (size_t i = 0; i < n; ++i) {
    const ClipScenario& s = (*scenarios)[i];
    center_ran[column[i]] = s.quality.converged && (!s.opening.computed || s.opening.converged);
  }
  halve_failed_points(
      &sp,
      [&](size_t k) {
        for (size_t c = 0; c < per; ++c) {
          const ClipScenario& s = flat[k * per + c];
          if (center_ran[c] &&
              (!s.quality.converged || (s.opening.computed && !s.opening.converged)))
            return true;
        }
        return false;
      },
      [&](const std::vector<size_t>& ks) {
        for (size_t k : ks) par[k] = post.apply(sp.points[k]);
        parallel_indices(ks.size() * per, jobs,
                         [&](size_t j) { run(ks[j / per] * per + j % per); });
      });
  for (size_t i = 0; i < n; ++i) {
    ClipScenario& s = (*scenarios)[i];
    ClipUncertainty& u = s.uncertainty;
    u.computed = true;
    u.at_points.resize(static_cast<Eigen::Index>(np), kClipOutcomes);
    u.failed = 0;
    for (size_t k = 0; k < np; ++k) {
      const ClipScenario& before = flat[k * per];
      const ClipScenario& here = flat[k * per + column[i]];
      if (!before.quality.converged) ++u.failed;
      if (column[i] > 0 && !here.quality.converged) ++u.failed;
      if (here.opening.computed && !here.opening.converged) ++u.failed;
      u.at_points.row(static_cast<Eigen::Index>(k)) =
          clip_outcomes(here, before.quality).transpose();
    }
    const Eigen::VectorXd at_center = clip_outcomes(s, before_at_center);
    u.sd_parameters = propagated_sd(sp, at_center, u.at_points);
    u.sd_mesh = Eigen::VectorXd::Zero(kClipOutcomes);
    u.at_refined =
        Eigen::VectorXd::Constant(kClipOutcomes, std::numeric_limits<double>::quiet_NaN());
    if (mesh.enabled) {
      const ClipScenario& before = flat[np * per];
      u.at_refined = clip_outcomes(flat[np * per + column[i]], before.quality);
      // A failed refined run leaves the outcome's SD unknown (NaN), as a failed sigma point does.
      u.sd_mesh = (u.at_refined - at_center).cwiseAbs();
    }
    u.sd = (u.sd_parameters.array().square() + u.sd_mesh.array().square()).sqrt().matrix();
  }
  return sp;
}

bool indistinguishable(const SigmaPoints& sp, const ClipScenario& a, const ClipScenario& b) {
  if (!a.uncertainty.computed || !b.uncertainty.computed) return false;
  if (!a.quality.converged || !b.quality.converged) return false;
  double sd = difference_sd(sp, a.quality.orifice.eroa_mm2, a.uncertainty.at_points.col(0),
                            b.quality.orifice.eroa_mm2, b.uncertainty.at_points.col(0));
  const ClipUncertainty &ua = a.uncertainty, &ub = b.uncertainty;
  const bool checked =
      ua.sd_mesh.size() > 0 && ub.sd_mesh.size() > 0 && (ua.sd_mesh[0] != 0 || ub.sd_mesh[0] != 0);
  if (checked) {
    // The mesh moves both: what counts is how much it moves their difference (NaN when a
    // refined run failed: then, as without intervals, no tie is claimed).
    const double mesh = (ua.at_refined[0] - ub.at_refined[0]) -
                        (a.quality.orifice.eroa_mm2 - b.quality.orifice.eroa_mm2);
    sd = std::sqrt(sd * sd + mesh * mesh);
  }
  if (!std::isfinite(sd)) return false;
  return std::abs(a.quality.orifice.eroa_mm2 - b.quality.orifice.eroa_mm2) <= kZ95 * sd;
}

}  // namespace mvtwin::inverse
