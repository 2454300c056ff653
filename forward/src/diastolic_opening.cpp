#include "mvtwin/forward/diastolic_opening.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "mvtwin/core/annulus_plane.h"
#include "mvtwin/core/closure_measures.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/units.h"
#include "mvtwin/forward/closure_scene.h"

namespace mvtwin::forward {

TriangleMesh clip_device_footprint(const ClosureResult& r, const AnnulusPlane& plane) {
  TriangleMesh out;
  out.V.resize(0, 3);
  out.F.resize(0, 3);
  const Eigen::Vector3d n = plane.normal;
  const Eigen::Vector3d e1 = n.unitOrthogonal(), e2 = n.cross(e1);
  for (const ClipGrasp& g : r.clip_grasps) {
    std::vector<Eigen::Vector3d> pts;
    for (const std::vector<int>* band : {&g.anterior_band, &g.posterior_band}) {
      for (int i : *band) {
        if (3 * static_cast<Eigen::Index>(i) + 2 < r.positions.size())
          pts.push_back(r.positions.segment<3>(3 * static_cast<Eigen::Index>(i)));
      }
    }
    if (pts.size() < 3) continue;
    // Andrew's monotone chain on the projected points.
    std::vector<int> order(pts.size());
    for (size_t i = 0; i < pts.size(); ++i) order[i] = static_cast<int>(i);
    auto xy = [&](int i) {
      return Eigen::Vector2d(e1.dot(pts[static_cast<size_t>(i)]),
                             e2.dot(pts[static_cast<size_t>(i)]));
    };
    std::sort(order.begin(), order.end(), [&](int a, int b) {
      const Eigen::Vector2d pa = xy(a), pb = xy(b);
      return pa.x() < pb.x() || (pa.x() == pb.x() && pa.y() < pb.y());
    });
    auto cross = [&](int o, int a, int b) {
      const Eigen::Vector2d po = xy(o), pa = xy(a) - po, pb = xy(b) - po;
      // Points on an edge (to rounding) are not corners.
      const double c = pa.x() * pb.y() - pa.y() * pb.x();
      return std::abs(c) <= 1e-12 * pa.norm() * pb.norm() ? 0.0 : c;
    };
    std::vector<int> hull(2 * order.size());
    size_t k = 0;
    for (int i : order) {
      while (k >= 2 && cross(hull[k - 2], hull[k - 1], i) <= 0) --k;
      hull[k++] = i;
    }
    for (size_t j = order.size() - 1, lo = k + 1; j-- > 0;) {
      const int i = order[j];
      while (k >= lo && cross(hull[k - 2], hull[k - 1], i) <= 0) --k;
      hull[k++] = i;
    }
    hull.resize(k - 1);
    if (hull.size() < 3) continue;
    const Eigen::Index v0 = out.V.rows();
    out.V.conservativeResize(v0 + static_cast<Eigen::Index>(hull.size()), 3);
    for (size_t j = 0; j < hull.size(); ++j)
      out.V.row(v0 + static_cast<Eigen::Index>(j)) = pts[static_cast<size_t>(hull[j])].transpose();
    const Eigen::Index f0 = out.F.rows();
    out.F.conservativeResize(f0 + static_cast<Eigen::Index>(hull.size()) - 2, 3);
    for (size_t j = 1; j + 1 < hull.size(); ++j)
      out.F.row(f0 + static_cast<Eigen::Index>(j) - 1) << static_cast<int>(v0),
          static_cast<int>(v0 + static_cast<Eigen::Index>(j)),
          static_cast<int>(v0 + static_cast<Eigen::Index>(j) + 1);
  }
  return out;
}

bool DiastoleOptions::is_valid(std::string* error) const {
  auto bad = [&](const char* m) {
    *error = m;
    return false;
  };
  if (!(transmitral_mmhg > 0 && transmitral_mmhg <= 50))
    return bad("diastole: transmitral pressure must be in (0, 50] mmHg");
  if (!(stroke_volume_ml > 0 && stroke_volume_ml <= 300))
    return bad("diastole: stroke volume must be in (0, 300] mL");
  if (!(filling_time_s > 0 && filling_time_s <= 2))
    return bad("diastole: filling time must be in (0, 2] s");
  if (!(stenosis_mva_cm2 > 0 && stenosis_gradient_mmhg > 0))
    return bad("diastole: stenosis thresholds must be positive");
  return true;
}

double gorlin_mean_gradient_mmhg(double flow_ml_per_s, double mva_cm2) {
  if (!(mva_cm2 > 0)) return std::numeric_limits<double>::infinity();
  const double r = flow_ml_per_s / (37.7 * mva_cm2);
  return r * r;
}

DiastolicOpening simulate_diastole(const ValveSequence& seq, const ValveParameters& par,
                                   const ClosureOptions& options, const DiastoleOptions& d) {
  if (std::string why; !d.is_valid(&why)) throw Error(why);
  if (seq.end_diastole < 0) throw Error("diastole: the sequence has no end-diastolic frame");
  // The widest open frame up to end-diastole.
  int open = -1;
  double widest = -1.0;
  for (int f = 0; f <= seq.end_diastole; ++f) {
    const ValveFrame& fr = seq.frames[static_cast<size_t>(f)];
    if (!fr.la_surface) continue;
    const double a = measure_closure(fr).orifice_area_mm2;
    if (a > widest) {
      widest = a;
      open = f;
    }
  }
  if (open < 0) throw Error("diastole: no frame up to end-diastole has leaflets");
  // The closure's grasp (insertions from its geometry) before the frames are moved.
  ClosureOptions o = options;
  for (size_t c = 0; c < o.clips.size(); ++c) {
    ClipOptions& clip = o.clips[c];
    if (clip.width_mm > 0) {
      const auto [ia, ip] = clip_insertion_mm(seq, clip);
      clip.anterior_insertion_mm = std::max(ia, 1e-3);
      clip.posterior_insertion_mm = std::max(ip, 1e-3);
    }
  }
  // The widest frame first; should the clips' grasp on it fail (the bands pulled together from
  // wide open can fold a leaflet through the other), the end-diastolic frame, as the closure
  // grasps.
  std::vector<int> frames{open};
  if (seq.end_diastole != open && !o.clips.empty()) frames.push_back(seq.end_diastole);
  DiastolicOpening out;
  for (int f : frames) {
    ValveSequence s = seq;
    s.end_diastole = f;
    s.first_closed = f + 1;
    ClosureOptions of = o;
    of.annulus_motion = false;
    of.papillary_motion = false;
    of.orifice_refine = 0;  // an open valve has no regurgitant orifice to measure
    ValveParameters p = par;
    p.peak_pressure_mpa = -units::mmhg_to_mpa(d.transmitral_mmhg);
    // Contact as stiff as in the closure (its penalty scales with the peak pressure,
    // SelfContactOptions::stiffness_per_area): the clip phase's ties pull as hard here as there,
    // and the few mmHg of diastole would leave a contact 12 times softer that lets a free edge
    // beside the grasp through the other leaflet.
    of.contact.stiffness_factor =
        std::min(1000.0, of.contact.stiffness_factor *
                             SelfContactOptions::scaling_pressure_mpa(par.peak_pressure_mpa) /
                             SelfContactOptions::scaling_pressure_mpa(p.peak_pressure_mpa));
    if (out.frame >= 0) out.fallback = "on frame " + std::to_string(out.frame) + ": " + out.reason;
    out.frame = f;
    try {
      out.result = simulate_closure(s, p, of);
      out.converged = out.result.summary.converged();
      out.reason = out.result.summary.reason;
    } catch (const Error& e) {
      out.converged = false;
      out.reason = e.what();
    }
    if (out.converged) break;
  }
  if (!out.converged || out.result.samples.empty()) return out;
  const ClosureSample& last = out.result.samples.back();
  // The openings between the leaflets and around the device: what the device and the tissue it
  // holds cover is closed (the arms hold the leaflets apart by the device's body, which blocks
  // the flow as in systole's RegurgitantOrifice::blocked).
  const auto annulus = last.la_surface.points().topRows(last.la_surface.ures());
  TriangleMesh leaflets = last.la_surface.triangulate();
  const TriangleMesh device = clip_device_footprint(out.result, least_squares_plane(annulus));
  if (device.F.rows() > 0) {
    const Eigen::Index nv = leaflets.V.rows(), nf = leaflets.F.rows();
    leaflets.V.conservativeResize(nv + device.V.rows(), 3);
    leaflets.V.bottomRows(device.V.rows()) = device.V;
    leaflets.F.conservativeResize(nf + device.F.rows(), 3);
    leaflets.F.bottomRows(device.F.rows()) = device.F.array() + static_cast<int>(nv);
  }
  const ClosureMeasures m = measure_closure(annulus, leaflets, 0.2);
  out.mva_cm2 = units::mm2_to_cm2(m.orifice_area_mm2);
  for (double a : m.component_areas_mm2) out.openings_cm2.push_back(units::mm2_to_cm2(a));
  out.gradient_mmhg = gorlin_mean_gradient_mmhg(d.stroke_volume_ml / d.filling_time_s, out.mva_cm2);
  out.stenosis = out.mva_cm2 < d.stenosis_mva_cm2 || out.gradient_mmhg >= d.stenosis_gradient_mmhg;
  return out;
}

}  // namespace mvtwin::forward
