#include "mvtwin/core/virtual_patient.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <vector>

#include <Eigen/Geometry>

#include "mvtwin/core/annulus_plane.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/rng.h"
#include "mvtwin/core/units.h"
#include "mvtwin/core/version.h"

namespace mvtwin {
namespace {

using std::numbers::pi;
using Curve = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
constexpr double kDeg = pi / 180.0;

double smoothstep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

/// Everything drawn for one patient, in the valve frame (x anterior, y anterolateral, z atrium),
/// at end-diastole unless the name says otherwise.
struct Draw {
  Pathology pathology = Pathology::kNormal;
  // annulus
  double alpm_diameter = 0, ap_diameter = 0, anterior_fraction = 0, commissure_angle = 0;
  double height_ratio_ed = 0, height_ratio_closed = 0;
  double ap_over_intertrigonal = 0;
  double contraction = 0;  // relative diameter reduction ED -> first closed
  double apical_excursion = 0;
  // leaflets
  double al_length = 0, pl_length = 0, commissure_length = 0;
  double al_opening_ed = 0, pl_opening_ed = 0;
  double al_opening = 0, pl_opening = 0, bulge = 0, scallop_depth = 0;
  // The commissures' angle below the annulus plane at end-diastole (set_commissure_opening_ed).
  double commissure_opening_ed = 0;
  // The widest (early-diastolic) orifice the opening angles are set to: the free-edge loop
  // projected on the annulus plane, cm^2 (docs/virtual-patients.md, "Diastolic orifice").
  double orifice_target_cm2 = 0;
  double annulus_dilation = 1.0;  // area ratio of a dilated annulus to the drawn normal one
  // papillary tips
  double papillary_depth = 0, papillary_separation = 0, papillary_posterior = 0;
  double papillary_asymmetry = 0, papillary_rise = 0;
  // Where the tips stood before a functional-MR ventricle displaced them: the chordae keep the
  // lengths they had there (tethering).
  double papillary_depth_normal = 0, papillary_separation_normal = 0;
  // timing
  double heart_rate_bpm = 0;
  int frames = 0, closure_frames = 0;
  ValveParameters hidden;
  // Torn marginal chordae: sites k of the default 28, k/28 along the free edge.
  std::vector<int> ruptured;
};

/// A flail scallop: `count` adjacent marginal chordae torn, centred on one posterior scallop (0:
/// P3, next to the posteromedial commissure, 1: P2, 2: P1). Sites of the default 28, k/28 along
/// the free edge: the posterior leaflet's 13 are 15-27, the scallops a third of them each, centred
/// at 16.3, 21 and 25.7.
std::vector<int> flail_scallop_chordae(int scallop, int count) {
  constexpr double kFirst = 14.0, kPerScallop = 14.0 / 3.0;  // the posterior arc: sites 14-28
  const double centre = kFirst + (scallop + 0.5) * kPerScallop;
  int first = static_cast<int>(std::lround(centre - 0.5 * (count - 1)));
  first = std::clamp(first, 15, 28 - count);
  std::vector<int> out;
  for (int k = 0; k < count; ++k) out.push_back(first + k);
  return out;
}

Pathology draw_pathology(Rng& rng) {
  // Cohort mix: mostly normal and functional MR, as in an MR clinic's referrals.
  const double r = rng.uniform();
  if (r < 0.40) return Pathology::kNormal;
  if (r < 0.55) return Pathology::kProlapseElongatedChordae;
  if (r < 0.65) return Pathology::kProlapseRupturedChordae;
  if (r < 0.85) return Pathology::kFunctionalMr;
  return Pathology::kStiffLeaflets;
}

/// With `o.taut_chordae_lengths` a ruptured-chordae patient's torn chordae are one scallop's
/// (docs/virtual-patients.md "Flail scallops"), not 1-3 of them; `o.myxomatous_flail` and
/// `o.tethering_scale` set the severity of flails and of functional MR ("Severity as the clinic
/// sees it"). No option changes which numbers are drawn: the rest of the patient stays the same.
Draw draw_anatomy(Rng& rng, Pathology pathology, const VirtualPatientOptions& o) {
  const bool flail_scallops = o.taut_chordae_lengths;
  Draw d;
  d.pathology = pathology;
  // Annulus at end-diastole (docs/virtual-patients.md: AL-PM 35->39 mm, AP 24->29 mm, AP/IT 1.11,
  // LM/IT 1.44, height/commissural width 10.6 +- 3.7 % in diastole, 13.5 % early systole).
  d.alpm_diameter = rng.truncated_normal(39.5, 2.5, 33.0, 46.0);
  d.ap_diameter = d.alpm_diameter * rng.truncated_normal(0.77, 0.035, 0.68, 0.86);
  d.anterior_fraction = rng.truncated_normal(0.30, 0.03, 0.22, 0.38);
  d.commissure_angle = rng.truncated_normal(66.0, 4.0, 56.0, 76.0) * kDeg;
  d.height_ratio_ed = rng.truncated_normal(0.106, 0.025, 0.05, 0.17);
  d.height_ratio_closed = d.height_ratio_ed + rng.uniform(0.015, 0.045);
  d.ap_over_intertrigonal = rng.truncated_normal(1.11, 0.05, 0.98, 1.25);
  d.contraction = rng.uniform(0.04, 0.10);
  d.apical_excursion = rng.uniform(1.0, 3.0);
  // Leaflets (radial length at mid-leaflet: anterior 21-26 mm, posterior 14-16 mm).
  d.al_length = rng.truncated_normal(23.5, 1.3, 20.5, 26.5);
  d.pl_length = rng.truncated_normal(15.0, 0.7, 13.5, 16.8);
  d.commissure_length = rng.truncated_normal(10.0, 1.0, 8.0, 12.0);
  // Opening angles below the annulus plane: widest in early diastole (mitral valve area 4-6 cm^2),
  // partly closed again at end-diastole after the atrial kick (pre-closure), where the closure
  // simulation starts.
  d.al_opening = rng.truncated_normal(75.0, 3.0, 66.0, 84.0) * kDeg;
  d.pl_opening = rng.truncated_normal(69.0, 3.0, 60.0, 78.0) * kDeg;
  d.al_opening_ed = rng.truncated_normal(58.0, 3.0, 50.0, 66.0) * kDeg;
  // The drawn angles alone left a third of the normal valves' simulated valve area above 6 cm^2
  // (the free-edge loop 4.7-6.8 cm^2 on cohort seed 2026's normal patients): the widest angles
  // are instead scaled to an orifice, the patient's own draw of the anterior angle deciding where
  // in the normal range (no extra draw, so every later draw stays the same patient's).
  d.orifice_target_cm2 = std::clamp(4.3 + 0.3 * (d.al_opening / kDeg - 75.0) / 3.0, 3.8, 4.9);
  d.pl_opening_ed = rng.truncated_normal(50.0, 3.0, 42.0, 58.0) * kDeg;
  d.bulge = rng.uniform(0.06, 0.12);
  d.scallop_depth = rng.uniform(0.0, 0.12);
  // Papillary tips (26-27 mm below the annulus plane, ~30 mm apart).
  d.papillary_depth = rng.truncated_normal(26.5, 1.5, 22.0, 31.0);
  d.papillary_separation = rng.truncated_normal(30.0, 2.5, 24.0, 36.0);
  d.papillary_posterior = rng.truncated_normal(-4.0, 2.0, -9.0, 1.0);
  d.papillary_asymmetry = rng.normal(0.0, 1.0);
  d.papillary_rise = rng.uniform(2.0, 5.0);
  d.papillary_depth_normal = d.papillary_depth;
  d.papillary_separation_normal = d.papillary_separation;
  // Timing: 7-28 frames per cycle, closure over 2-4 frames, ~0.2 s.
  d.heart_rate_bpm = rng.truncated_normal(72.0, 10.0, 55.0, 100.0);
  d.frames = rng.uniform_int(7, 28);
  const double frame_dt = 60.0 / d.heart_rate_bpm / d.frames;
  const double closure_s = rng.truncated_normal(0.2, 0.04, 0.1, 0.3);
  d.closure_frames = std::clamp(static_cast<int>(std::lround(closure_s / frame_dt)), 2, 4);

  // Hidden tissue parameters around the paper's generic values.
  ValveParameters& h = d.hidden;
  for (double& f : h.restlength_factor) f = rng.truncated_normal(1.0, 0.04, 0.9, 1.1);
  h.marginal_stiffness_scale = rng.truncated_normal(1.0, 0.1, 0.7, 1.4);
  h.basal_stiffness_scale = rng.truncated_normal(1.0, 0.1, 0.7, 1.4);
  h.al_modulus_scale = rng.truncated_normal(1.0, 0.1, 0.7, 1.4);
  h.pl_modulus_scale = rng.truncated_normal(1.0, 0.1, 0.7, 1.4);
  h.peak_pressure_mpa = units::mmhg_to_mpa(rng.truncated_normal(120.0, 10.0, 95.0, 150.0));

  switch (pathology) {
    case Pathology::kNormal:
      break;
    case Pathology::kProlapseElongatedChordae: {
      // Myxomatous: redundant leaflets, mildly dilated annulus, elongated marginal chordae.
      const double redundancy = rng.uniform(1.05, 1.2);
      d.al_length *= redundancy;
      d.pl_length *= redundancy;
      const double dilation = rng.uniform(1.0, 1.1);
      d.alpm_diameter *= dilation;
      d.ap_diameter *= dilation;
      d.annulus_dilation = dilation * dilation;
      const int g = rng.uniform() < 0.5 ? 0 : 2;  // marginal group of one papillary side
      h.restlength_factor[g] = rng.uniform(1.2, 1.5);
      if (rng.uniform() < 0.3) h.restlength_factor[2 - g] = rng.uniform(1.15, 1.4);
      break;
    }
    case Pathology::kProlapseRupturedChordae: {
      d.pl_length *= rng.uniform(1.0, 1.15);
      // 1-3 adjacent marginal chordae torn, centred on the posterior scallops (P1-P3).
      const int n = rng.uniform_int(1, 3);
      const int first = rng.uniform_int(16, 26 - n);
      // A flail valve is myxomatous: its leaflets more extensible (failure strain 56 against 43 %
      // in other myxomatous leaflets; the modulus factor is chosen) and its chordae less stiff
      // (23.5 against 59.1 MPa), Mills et al. 2004, Am Heart J 148:144. With either reading of
      // the torn chordae below.
      if (o.myxomatous_flail) {
        h.pl_modulus_scale *= kFlailPosteriorModulus;
        h.marginal_stiffness_scale *= kFlailChordaeStiffness;
      }
      if (!flail_scallops) {
        for (int k = 0; k < n; ++k) d.ruptured.push_back(first + k);
        break;
      }
      // The same two draws read as a flail scallop (a few torn chordae leave a segment that its
      // neighbours still hold): 4-6 chordae; P2, the most common (Yuan 2009, Cardiol J 16:151),
      // unless the draw stands at either end: P3 and P1 one in 8-10 draws each.
      const int positions = 26 - n - 16 + 1, at = first - 16;
      d.ruptured = flail_scallop_chordae(at == 0 ? 0 : (at == positions - 1 ? 2 : 1), n + 3);
      break;
    }
    case Pathology::kFunctionalMr: {
      // Dilated, flattened annulus; papillary tips displaced apically and apart (tethering).
      const double dilation = rng.uniform(1.15, 1.35);
      d.alpm_diameter *= dilation;
      const double rounder = rng.uniform(1.0, 1.08);
      d.ap_diameter *= dilation * rounder;
      d.annulus_dilation = dilation * dilation * rounder;
      d.height_ratio_ed *= rng.uniform(0.6, 0.85);
      d.height_ratio_closed = d.height_ratio_ed + rng.uniform(0.0, 0.02);
      d.contraction *= 0.5;  // dysfunctional annulus contracts less
      d.papillary_depth += o.tethering_scale * rng.uniform(3.0, 7.0);
      d.papillary_separation += o.tethering_scale * rng.uniform(3.0, 8.0);
      // Leaflets enlarge with the annulus (Chaput et al. 2008): tethering, not missing tissue,
      // is what keeps them from coapting.
      const double growth = dilation * rng.uniform(0.95, 1.05);
      d.al_length *= growth;
      d.pl_length *= growth;
      h.peak_pressure_mpa = units::mmhg_to_mpa(rng.uniform(85.0, 115.0));  // weaker ventricle
      break;
    }
    case Pathology::kStiffLeaflets:
      h.al_modulus_scale = rng.uniform(1.5, 4.0);
      h.pl_modulus_scale = rng.uniform(1.5, 4.0);
      d.al_length *= rng.uniform(0.92, 1.0);
      d.pl_length *= rng.uniform(0.92, 1.0);
      break;
  }
  return d;
}

/// Annulus shape at one instant, as a function of the angle theta from the anterior point
/// (counter-clockwise seen from the atrium).
struct AnnulusShape {
  double a_anterior, a_posterior, b, height, commissure_angle, z_shift;

  Eigen::Vector3d at(double theta) const {
    const double c = std::cos(theta), s = std::sin(theta);
    // Saddle: highs at the anterior and posterior horns, lows at the commissures. The angle is
    // warped so that the commissures (at +-commissure_angle) map to +-90 degrees.
    double t = std::remainder(theta, 2.0 * pi);
    const double at = std::abs(t);
    const double warped = at <= commissure_angle ? at / commissure_angle * (pi / 2)
                                                 : pi / 2 + (at - commissure_angle) /
                                                                (pi - commissure_angle) * (pi / 2);
    return {(c >= 0 ? a_anterior : a_posterior) * c, b * s,
            0.5 * height * std::cos(2.0 * warped) + z_shift};
  }
};

/// Samples the annulus on the grid: u = 0 at the anterolateral commissure (theta = +tc), the
/// anterior arc to theta = -tc at u = ures/2, then the posterior arc back; each arc evenly in
/// arc length. Also returns the theta of every grid point.
Curve sample_annulus(const AnnulusShape& shape, int ures, std::vector<double>* thetas) {
  const double tc = shape.commissure_angle;
  Curve out(ures, 3);
  thetas->assign(ures, 0.0);
  auto sample_arc = [&](double theta0, double theta1, int u0, int count) {
    constexpr int kFine = 4000;
    std::vector<double> th(kFine + 1), len(kFine + 1, 0.0);
    for (int i = 0; i <= kFine; ++i) th[i] = theta0 + (theta1 - theta0) * i / kFine;
    for (int i = 1; i <= kFine; ++i)
      len[i] = len[i - 1] + (shape.at(th[i]) - shape.at(th[i - 1])).norm();
    for (int k = 0; k < count; ++k) {
      const double target = len[kFine] * k / count;
      const auto it = std::lower_bound(len.begin(), len.end(), target);
      const size_t i = std::max<size_t>(1, static_cast<size_t>(it - len.begin()));
      const double f = (target - len[i - 1]) / std::max(len[i] - len[i - 1], 1e-300);
      const double theta = th[i - 1] + f * (th[i] - th[i - 1]);
      (*thetas)[u0 + k] = theta;
      out.row(u0 + k) = shape.at(theta).transpose();
    }
  };
  sample_arc(tc, -tc, 0, ures / 2);                       // anterior
  sample_arc(-tc, -(2.0 * pi - tc), ures / 2, ures / 2);  // posterior
  return out;
}

/// Annulus at systolic activation a (0 in diastole, 1 at the first closed frame).
AnnulusShape annulus_shape(const Draw& d, double a) {
  const double k = 1.0 - d.contraction * a;
  const double height_ratio = d.height_ratio_ed + (d.height_ratio_closed - d.height_ratio_ed) * a;
  AnnulusShape shape{d.anterior_fraction * d.ap_diameter * k,
                     (1.0 - d.anterior_fraction) * d.ap_diameter * k,
                     0.5 * d.alpm_diameter * k,
                     0.0,
                     d.commissure_angle,
                     -d.apical_excursion * a};
  // Saddle height relative to the commissural width (as in the echo literature).
  shape.height = height_ratio * 2.0 * shape.b * std::sin(d.commissure_angle);
  return shape;
}

/// The commissures' angle below the annulus plane in early diastole: nearly vertical.
constexpr double kCommissureOpeningWidest = 84.0 * kDeg;

/// Open leaflet surface hanging from the annulus into the ventricle; `openness` 1 in early
/// diastole (widest), 0 at end-diastole.
LeafletGrid open_leaflets(const Draw& d, const Curve& annulus, int vres, double openness) {
  const int ures = static_cast<int>(annulus.rows());
  LeafletGrid::Points P(static_cast<Eigen::Index>(ures) * vres, 3);
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
  for (int u = 0; u < ures; ++u) {
    const bool anterior = u < ures / 2;
    const double s = anterior ? static_cast<double>(u) / (ures / 2)
                              : static_cast<double>(u - ures / 2) / (ures / 2);
    double g = std::pow(std::sin(pi * s), anterior ? 1.0 : 1.0);
    if (!anterior) {  // clefts between the posterior scallops P1/P2/P3
      g *= 1.0 - d.scallop_depth * (std::exp(-std::pow((s - 1.0 / 3) / 0.04, 2)) +
                                    std::exp(-std::pow((s - 2.0 / 3) / 0.04, 2)));
    }
    const double leaflet_length = anterior ? d.al_length : d.pl_length;
    const double L = d.commissure_length + (leaflet_length - d.commissure_length) * g;
    const double phi_leaf = anterior
                                ? d.al_opening_ed + (d.al_opening - d.al_opening_ed) * openness
                                : d.pl_opening_ed + (d.pl_opening - d.pl_opening_ed) * openness;
    // The commissures hang nearly vertically in early diastole and close with the leaflets
    // towards end-diastole (set_commissure_opening_ed).
    const double phi_c =
        d.commissure_opening_ed + (kCommissureOpeningWidest - d.commissure_opening_ed) * openness;
    const double phi = std::min(phi_c + (phi_leaf - phi_c) * g, 88.0 * kDeg);

    const Eigen::Vector3d A = annulus.row(u).transpose();
    const Eigen::Vector3d tangent =
        (annulus.row((u + 1) % ures) - annulus.row((u + ures - 1) % ures)).transpose();
    Eigen::Vector3d inward = tangent.cross(z);
    inward.z() = 0.0;
    inward.normalize();
    const Eigen::Vector3d dir = std::cos(phi) * inward - std::sin(phi) * z;
    const Eigen::Vector3d bulge = std::sin(phi) * inward + std::cos(phi) * z;
    for (int v = 0; v < vres; ++v) {
      const double t = static_cast<double>(v) / (vres - 1);
      P.row(static_cast<Eigen::Index>(v) * ures + u) =
          (A + L * (t * dir + d.bulge * g * std::sin(pi * t) * bulge)).transpose();
    }
  }
  return LeafletGrid(ures, vres, std::move(P));
}

/// Free-edge loop of a leaflet grid projected on the annulus plane, cm^2.
double free_edge_orifice_cm2(const LeafletGrid& g, const Curve& annulus) {
  const AnnulusPlane plane = least_squares_plane(annulus);
  Eigen::Vector3d va = Eigen::Vector3d::Zero();
  for (int u = 0; u < g.ures(); ++u)
    va += 0.5 * g.at(u, g.vres() - 1).cross(g.at((u + 1) % g.ures(), g.vres() - 1));
  return units::mm2_to_cm2(std::abs(va.dot(plane.normal)));
}

/// Sets the widest opening angles: from end-diastole's towards the drawn ones (one scale for
/// both leaflets, at most 88 degrees) until the early-diastolic free-edge loop reaches the
/// patient's target orifice (times the annulus' dilation); the nearest end when out of reach.
void set_widest_openings(Draw& d, int ures, int vres) {
  std::vector<double> thetas;
  const Curve annulus = sample_annulus(annulus_shape(d, 0.0), ures, &thetas);
  const double al = d.al_opening, pl = d.pl_opening;
  const double cap = 88.0 * kDeg;
  double hi = 1e9;
  if (al > d.al_opening_ed) hi = std::min(hi, (cap - d.al_opening_ed) / (al - d.al_opening_ed));
  if (pl > d.pl_opening_ed) hi = std::min(hi, (cap - d.pl_opening_ed) / (pl - d.pl_opening_ed));
  hi = std::min(hi, 3.0);
  auto apply = [&](double lambda) {
    d.al_opening = d.al_opening_ed + lambda * (al - d.al_opening_ed);
    d.pl_opening = d.pl_opening_ed + lambda * (pl - d.pl_opening_ed);
  };
  auto orifice = [&](double lambda) {
    apply(lambda);
    return free_edge_orifice_cm2(open_leaflets(d, annulus, vres, 1.0), annulus);
  };
  const double target = d.orifice_target_cm2 * d.annulus_dilation;
  double lo = 0.0;
  if (orifice(hi) <= target) return apply(hi);
  if (orifice(lo) >= target) return apply(lo);
  for (int it = 0; it < 40; ++it) {
    const double mid = 0.5 * (lo + hi);
    (orifice(mid) < target ? lo : hi) = mid;
  }
  apply(0.5 * (lo + hi));
}

/// Sets the commissures' end-diastolic angle: as far closed as the two leaflets beside them (the
/// mean of their end-diastolic angles), or as much steeper as keeps the end-diastolic surface
/// `clearance_mm` away from itself where it folds: the facing columns (u and ures - u, the same
/// distance from a commissure), and around each commissure any two points at least three quarters
/// of a column apart along the surface; hanging nearly vertically, as in early diastole, when it
/// is 0. A commissure that still hangs vertically when the closure starts leaves a notch open
/// beside it in the closed valve (docs/virtual-patients.md, "Closing anatomy").
void set_commissure_opening_ed(Draw& d, int ures, int vres, double clearance_mm) {
  d.commissure_opening_ed = kCommissureOpeningWidest;
  if (!(clearance_mm > 0.0)) return;
  std::vector<double> thetas;
  const Curve annulus = sample_annulus(annulus_shape(d, 0.0), ures, &thetas);
  // The grid's mean column spacing along the annulus, mm.
  double column = 0.0;
  for (int u = 0; u < ures; ++u)
    column += (annulus.row((u + 1) % ures) - annulus.row(u)).norm() / ures;
  // Whether the end-diastolic surface at this angle folds closer to itself than clearance_mm:
  // all the bisection below needs. The search stops at the first pair that close, and sweeps the
  // pairs around a commissure in the order of their x coordinate, skipping those farther apart
  // in x alone (with a margin for rounding): the same answer as measuring every pair, which took
  // 84 % of a virtual patient's time.
  auto folds = [&](double angle) {
    d.commissure_opening_ed = angle;
    const LeafletGrid g = open_leaflets(d, annulus, vres, 0.0);
    // Facing columns (u and ures - u).
    for (int u = 1; u < ures / 2; ++u) {
      for (int v = 1; v < vres; ++v) {
        for (int w = 1; w < vres; ++w)
          if ((g.at(u, v) - g.at(ures - u, w)).norm() < clearance_mm) return true;
      }
    }
    // Around each commissure, within kBeside columns on either side and at quarter columns (the
    // surface between the grid's columns folds too; half columns left 3 of 75 patients with
    // slivers at 40 x 40): points at least three quarters of a column apart along the surface
    // keep the clearance in space. Folded tighter than that, the models' elements across the
    // fold are slivers (quality 0.002 at 30 x 30).
    constexpr int kBeside = 4, kSub = 4;
    const double x_apart = clearance_mm * (1.0 + 1e-9);
    for (const double c : {0.0, 0.5}) {
      std::vector<Eigen::Vector3d> x;
      std::vector<Eigen::Vector2d> plane;  // (along the annulus, along the column), mm
      double along = 0.0;
      Eigen::Vector3d previous_annulus = Eigen::Vector3d::Zero();
      for (int k = -kBeside * kSub; k <= kBeside * kSub; ++k) {
        const double s = c + static_cast<double>(k) / (kSub * ures);
        const Eigen::Vector3d a0 = g.sample(s, 0.0);
        if (k > -kBeside * kSub) along += (a0 - previous_annulus).norm();
        previous_annulus = a0;
        double depth = 0.0;
        Eigen::Vector3d previous = a0;
        for (int v = 1; v < vres; ++v) {
          const Eigen::Vector3d p = g.sample(s, static_cast<double>(v) / (vres - 1));
          depth += (p - previous).norm();
          previous = p;
          x.push_back(p);
          plane.emplace_back(along, depth);
        }
      }
      std::vector<size_t> order(x.size());
      std::iota(order.begin(), order.end(), size_t{0});
      std::sort(order.begin(), order.end(),
                [&](size_t a, size_t b) { return x[a].x() < x[b].x(); });
      for (size_t a = 0; a < order.size(); ++a) {
        const size_t i = order[a];
        for (size_t b = a + 1; b < order.size(); ++b) {
          const size_t j = order[b];
          if (x[j].x() - x[i].x() > x_apart) break;
          if ((plane[i] - plane[j]).norm() < 0.75 * column) continue;
          if ((x[i] - x[j]).norm() < clearance_mm) return true;
        }
      }
    }
    return false;
  };
  double lo = 0.5 * (d.al_opening_ed + d.pl_opening_ed), hi = kCommissureOpeningWidest;
  if (lo >= hi || !folds(lo)) {
    d.commissure_opening_ed = std::min(lo, hi);
    return;
  }
  for (int it = 0; it < 30; ++it) {
    const double mid = 0.5 * (lo + hi);
    (folds(mid) ? lo : hi) = mid;
  }
  d.commissure_opening_ed = hi;
}

/// Rest-length factor per chordae group at which the chordae are just taut when the valve is
/// closed, from a geometric estimate of the closed valve at the first closed frame: facing
/// leaflet columns (fractions s and 1-s of the way round, i.e. the same distance from the
/// anterolateral commissure) meet on the chord between their annulus points, each reaching in
/// proportion to its length, and their excess length hangs together into the ventricle (the
/// coaptation zone). Chordae sites follow Mansi et al. 2012, Sec. 2.2 (28 marginal on the free
/// edge, 8 basal at mid-leaflet); a chorda belongs to the anterolateral papillary tip when s < 1/4
/// or s >= 3/4. Everything in the valve frame.
///
/// Also each marginal chorda's length (to the tips where the chordae grew, `tip_al_grown` and
/// `tip_pm_grown`: the closed tips, or a functional-MR ventricle's tips before it displaced
/// them), just taut in the same estimate but never shorter than at end-diastole: one factor per
/// group cannot make the chordae of both leaflets taut at once (docs/virtual-patients.md,
/// "Closing anatomy").
struct TautChordae {
  std::array<double, kNumChordaeGroups> factor{};
  std::vector<ChordaLength> marginal;
};

TautChordae closure_taut_restlength(const LeafletGrid& ed, const Curve& annulus_closed,
                                    const Eigen::Vector3d& tip_al_ed,
                                    const Eigen::Vector3d& tip_pm_ed,
                                    const Eigen::Vector3d& tip_al_closed,
                                    const Eigen::Vector3d& tip_pm_closed,
                                    const Eigen::Vector3d& tip_al_grown,
                                    const Eigen::Vector3d& tip_pm_grown) {
  const int ures = ed.ures();
  const Curve dense = resample_closed_curve(annulus_closed, 16 * ures);
  auto annulus_at = [&](double s) -> Eigen::Vector3d {
    const int n = static_cast<int>(dense.rows());
    return dense.row(static_cast<int>(std::lround((s - std::floor(s)) * n)) % n).transpose();
  };
  const Eigen::Vector3d down = -Eigen::Vector3d::UnitZ();
  std::array<double, kNumChordaeGroups> sum{}, count{};
  TautChordae out;
  auto add = [&](double s, bool marginal) {
    const double partner = 1.0 - s;
    const double L = ed.radial_length_at(s), Lp = ed.radial_length_at(partner);
    const Eigen::Vector3d A = annulus_at(s), Ap = annulus_at(partner);
    const double chord = (Ap - A).norm();
    const Eigen::Vector3d meet = A + (L / (L + Lp)) * (Ap - A);
    const Eigen::Vector3d closed =
        marginal ? Eigen::Vector3d(meet + down * std::max(0.0, 0.5 * (L + Lp - chord)))
                 : Eigen::Vector3d(A + 0.5 * (meet - A));
    const Eigen::Vector3d open = ed.sample(s, marginal ? 1.0 : 0.5);
    const bool anterolateral = s < 0.25 || s >= 0.75;
    const int g = (anterolateral ? 0 : 2) + (marginal ? 0 : 1);
    const Eigen::Vector3d& t_ed = anterolateral ? tip_al_ed : tip_pm_ed;
    const Eigen::Vector3d& t_cl = anterolateral ? tip_al_closed : tip_pm_closed;
    sum[g] += (closed - t_cl).norm() / (open - t_ed).norm();
    count[g] += 1.0;
    // Never shorter than at end-diastole: chordae are at most just taut in diastole.
    if (marginal)
      out.marginal.push_back(
          {s, std::max((closed - (anterolateral ? tip_al_grown : tip_pm_grown)).norm(),
                       (open - t_ed).norm())});
  };
  for (int k = 0; k < 28; ++k) add(k / 28.0, true);
  for (int i = 0; i < 4; ++i) {
    add((2 * i + 1) / 8.0, false);
    add((2 * i + 1) / 8.0 + 1.0 / ures, false);
  }
  for (int g = 0; g < kNumChordaeGroups; ++g) out.factor[g] = sum[g] / count[g];
  return out;
}

Eigen::Matrix4d draw_pose(Rng& rng) {
  // A probe-like placement: the valve about 7 cm deep, rotated by up to 30 degrees.
  Eigen::Vector3d axis(rng.normal(), rng.normal(), rng.normal());
  axis.normalize();
  const double angle = rng.uniform(0.0, 30.0) * kDeg;
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
  pose.topLeftCorner<3, 3>() = Eigen::AngleAxisd(angle, axis).toRotationMatrix();
  pose.topRightCorner<3, 1>() =
      Eigen::Vector3d(rng.normal(0, 5), rng.normal(0, 5), 70.0 + rng.normal(0, 5));
  return pose;
}

}  // namespace

bool VirtualPatientOptions::is_valid(std::string* error) const {
  if (ures < 8 || ures % 2 != 0) {
    *error = "ures must be even and at least 8 (got " + std::to_string(ures) + ")";
    return false;
  }
  if (vres < 3) {
    *error = "vres must be at least 3 (got " + std::to_string(vres) + ")";
    return false;
  }
  if (!(tethering_scale >= 0.0 && tethering_scale <= 3.0)) {
    *error = "the functional-MR tethering scale must be 0-3 (got " +
             std::to_string(tethering_scale) + ")";
    return false;
  }
  if (!(commissure_clearance_mm >= 0.0 && commissure_clearance_mm <= 10.0)) {
    *error = "the commissures' end-diastolic clearance must be 0-10 mm (got " +
             std::to_string(commissure_clearance_mm) + ")";
    return false;
  }
  return true;
}

Patient make_virtual_patient(std::uint64_t seed, const VirtualPatientOptions& options) {
  std::string error;
  if (!options.is_valid(&error)) throw Error("virtual patient: " + error);
  Rng rng(seed);
  const Pathology pathology = options.pathology ? *options.pathology : draw_pathology(rng);
  Draw d = draw_anatomy(rng, pathology, options);
  const Eigen::Matrix4d pose = draw_pose(rng);
  const int ures = options.ures, vres = options.vres;
  set_widest_openings(d, ures, vres);
  set_commissure_opening_ed(d, ures, vres, options.commissure_clearance_mm);

  // Phases: diastolic frames first; the closure takes `closure_frames` frames after
  // end-diastole; then systole.
  const double period = 60.0 / d.heart_rate_bpm;
  const double frame_dt = period / d.frames;
  const int ed = std::max(
      1, d.frames - 1 - std::max(d.closure_frames, static_cast<int>(std::lround(0.35 * d.frames))));
  const int fc = ed + d.closure_frames;
  const double t_ed = ed * frame_dt, t_fc = fc * frame_dt, t_end = (d.frames - 1) * frame_dt;

  const double intertrigonal = d.ap_diameter / d.ap_over_intertrigonal;

  Patient p;
  p.id = options.id.empty() ? "virtual-" + std::to_string(seed) : options.id;
  p.synthetic = true;
  p.provenance.version = kVersion;
  p.provenance.command = options.command;
  p.provenance.created_utc = utc_now_iso8601();
  p.provenance.seed = seed;
  p.provenance.source =
      "mvtwin virtual patient generator (geometric open frames; docs/virtual-patients.md)";
  ValveSequence& seq = p.sequence;
  seq.ures = ures;
  seq.vres = vres;
  seq.end_diastole = ed;
  seq.first_closed = fc;

  const Eigen::Matrix3d R = pose.topLeftCorner<3, 3>();
  const Eigen::Vector3d T = pose.topRightCorner<3, 1>();
  auto to_image = [&](const Eigen::Vector3d& x) -> Eigen::Vector3d { return R * x + T; };

  // Valve-frame copies for the rest-length estimate.
  std::optional<LeafletGrid> ed_surface_valve;
  Curve annulus_closed_valve;
  Eigen::Vector3d tips_ed[2], tips_closed[2], tips_grown[2];

  for (int f = 0; f < d.frames; ++f) {
    const double t = f * frame_dt;
    // Systolic activation: 0 in diastole, rising to 1 at the first closed frame (the annulus is
    // smallest at 11-13 % of systole), then the annulus re-enlarges towards end-systole.
    double a = 0.0;
    if (t > t_ed && t <= t_fc) a = smoothstep((t - t_ed) / (t_fc - t_ed));
    if (t > t_fc) a = 1.0 - 0.6 * (t - t_fc) / std::max(t_end - t_fc, 1e-9);
    const double k = 1.0 - d.contraction * a;
    const AnnulusShape shape = annulus_shape(d, a);
    std::vector<double> thetas;
    const Curve annulus_v = sample_annulus(shape, ures, &thetas);

    ValveFrame fr;
    fr.time_s = t;
    Curve annulus(ures, 3);
    for (int u = 0; u < ures; ++u)
      annulus.row(u) = to_image(annulus_v.row(u).transpose()).transpose();
    fr.annulus = annulus;

    auto set = [&](Landmark l, const Eigen::Vector3d& x_valve) {
      fr.landmarks[index(l)] = to_image(x_valve);
      fr.landmark_observed[index(l)] = true;
    };
    const double trigone_theta = std::asin(std::min(0.5 * intertrigonal * k / shape.b, 0.99));
    set(Landmark::kAnterolateralTrigone, shape.at(trigone_theta));
    set(Landmark::kPosteromedialTrigone, shape.at(-trigone_theta));
    set(Landmark::kPosteriorAnnulusMidpoint, annulus_v.row(3 * ures / 4).transpose());
    set(Landmark::kAnterolateralCommissure, annulus_v.row(0).transpose());
    set(Landmark::kPosteromedialCommissure, annulus_v.row(ures / 2).transpose());
    auto tip = [&](double separation, double depth, int side) -> Eigen::Vector3d {
      const double sep = 0.5 * separation * (1.0 - 0.05 * a);
      const double pz = shape.z_shift - depth + d.papillary_rise * a;
      return side == 0
                 ? Eigen::Vector3d(d.papillary_posterior + 0.5 * d.papillary_asymmetry, sep, pz)
                 : Eigen::Vector3d(d.papillary_posterior - 0.5 * d.papillary_asymmetry, -sep,
                                   pz - 0.5 * d.papillary_asymmetry);
    };
    const Eigen::Vector3d tip_al = tip(d.papillary_separation, d.papillary_depth, 0);
    const Eigen::Vector3d tip_pm = tip(d.papillary_separation, d.papillary_depth, 1);
    set(Landmark::kAnterolateralPapillaryTip, tip_al);
    set(Landmark::kPosteromedialPapillaryTip, tip_pm);
    if (f == ed) {
      tips_ed[0] = tip_al;
      tips_ed[1] = tip_pm;
    }
    if (f == fc) {
      tips_closed[0] = tip_al;
      tips_closed[1] = tip_pm;
      for (int side = 0; side < 2; ++side)
        tips_grown[side] = tip(d.papillary_separation_normal, d.papillary_depth_normal, side);
      annulus_closed_valve = annulus_v;
    }

    for (Landmark l : {Landmark::kAnteriorLeafletTip, Landmark::kPosteriorLeafletTip}) {
      fr.landmarks[index(l)].setConstant(std::numeric_limits<double>::quiet_NaN());
      fr.landmark_observed[index(l)] = false;
    }
    if (f <= ed) {
      // Open frames: widest in early diastole, partly closed at end-diastole.
      const double openness = 1.0 - t / std::max(t_ed, 1e-9);
      LeafletGrid g = open_leaflets(d, annulus_v, vres, openness);
      if (f == ed) ed_surface_valve = g;
      for (Eigen::Index i = 0; i < g.points().rows(); ++i) {
        g.points().row(i) = to_image(g.points().row(i).transpose()).transpose();
      }
      g.points().topRows(ures) = annulus;  // exact equality with the annulus curve
      set(Landmark::kAnteriorLeafletTip, R.transpose() * (g.sample(0.25, 1.0) - T));
      set(Landmark::kPosteriorLeafletTip, R.transpose() * (g.sample(0.75, 1.0) - T));
      fr.la_surface = std::move(g);
    }
    seq.frames.push_back(std::move(fr));
  }

  // Chordae: each marginal chorda as long as it is taut in the estimated closed valve (anatomy
  // the sequence records, as the images would show it); the basal groups' factors where they are
  // just taut there. Both times the patient's own variation and its pathology (elongation).
  const TautChordae taut_chordae =
      closure_taut_restlength(*ed_surface_valve, annulus_closed_valve, tips_ed[0], tips_ed[1],
                              tips_closed[0], tips_closed[1], tips_grown[0], tips_grown[1]);
  const std::array<double, kNumChordaeGroups>& taut = taut_chordae.factor;
  if (options.taut_chordae_lengths) seq.marginal_chordae_lengths = taut_chordae.marginal;
  VirtualTruth truth;
  truth.pathology = pathology;
  truth.parameters = d.hidden;
  for (int g = 0; g < kNumChordaeGroups; ++g) {
    const bool basal = g == static_cast<int>(ChordaeGroup::kAnterolateralBasal) ||
                       g == static_cast<int>(ChordaeGroup::kPosteromedialBasal);
    if (basal || !options.taut_chordae_lengths) truth.parameters.restlength_factor[g] *= taut[g];
  }
  // Torn chordae are anatomy: one stretch over the adjacent marginal chordae of the default 28.
  if (!d.ruptured.empty()) {
    const ChordaeRupture first = marginal_chorda_rupture(d.ruptured.front(), 28);
    const ChordaeRupture last = marginal_chorda_rupture(d.ruptured.back(), 28);
    seq.ruptured_chordae.push_back({first.s_begin, last.s_end});
  }
  truth.pose = pose;
  truth.closed_frames =
      "missing: frames after end_diastole have no leaflet surface yet; they must be simulated with "
      "the hidden parameters by a finer model than the calibration model (forward simulator, "
      "issue 3)";
  truth.anatomy = {
      {"alpm_diameter_ed_mm", d.alpm_diameter},
      {"ap_diameter_ed_mm", d.ap_diameter},
      {"anterior_fraction_of_ap", d.anterior_fraction},
      {"commissure_angle_deg", d.commissure_angle / kDeg},
      {"height_ratio_ed", d.height_ratio_ed},
      {"height_ratio_first_closed", d.height_ratio_closed},
      {"ap_over_intertrigonal", d.ap_over_intertrigonal},
      {"annulus_contraction", d.contraction},
      {"annulus_apical_excursion_mm", d.apical_excursion},
      {"al_length_mm", d.al_length},
      {"pl_length_mm", d.pl_length},
      {"commissure_leaflet_length_mm", d.commissure_length},
      {"widest_orifice_target_cm2", d.orifice_target_cm2 * d.annulus_dilation},
      {"al_opening_deg", d.al_opening / kDeg},
      {"pl_opening_deg", d.pl_opening / kDeg},
      {"al_opening_ed_deg", d.al_opening_ed / kDeg},
      {"pl_opening_ed_deg", d.pl_opening_ed / kDeg},
      {"commissure_opening_ed_deg", d.commissure_opening_ed / kDeg},
      {"commissure_clearance_ed_mm", options.commissure_clearance_mm},
      {"myxomatous_flail", options.myxomatous_flail ? 1.0 : 0.0},
      {"tethering_scale", options.tethering_scale},
      {"leaflet_bulge", d.bulge},
      {"scallop_depth", d.scallop_depth},
      {"papillary_depth_mm", d.papillary_depth},
      {"papillary_separation_mm", d.papillary_separation},
      {"papillary_posterior_offset_mm", d.papillary_posterior},
      {"papillary_rise_mm", d.papillary_rise},
      {"heart_rate_bpm", d.heart_rate_bpm},
      {"frames_per_cycle", static_cast<double>(d.frames)},
      {"closure_frames", static_cast<double>(d.closure_frames)},
      {"closure_duration_s", t_fc - t_ed},
  };
  for (int g = 0; g < kNumChordaeGroups; ++g) {
    truth.anatomy.emplace_back("restlength_taut_" + std::string(kChordaeGroupNames[g]), taut[g]);
  }
  p.truth = std::move(truth);
  seq.validate(("virtual patient " + p.id).c_str());
  return p;
}

CohortMember cohort_member(std::uint64_t cohort_seed, int index) {
  if (index < 0) throw Error("cohort_member: negative patient index " + std::to_string(index));
  std::uint64_t z = cohort_seed + 0x9E3779B97F4A7C15ull * static_cast<std::uint64_t>(index + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  CohortMember m;
  m.seed = (z ^ (z >> 31)) & 0x7FFFFFFFFFFFFFFFull;  // positive when stored as int64
  m.pathology = static_cast<Pathology>(index % kNumPathologies);
  m.id = "virtual-" + std::to_string(cohort_seed) + "-" + std::to_string(index);
  return m;
}

Patient make_cohort_patient(std::uint64_t cohort_seed, int index, VirtualPatientOptions options) {
  const CohortMember m = cohort_member(cohort_seed, index);
  options.pathology = m.pathology;
  options.id = m.id;
  return make_virtual_patient(m.seed, options);
}

}  // namespace mvtwin
