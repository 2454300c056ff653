#include "mvtwin/core/regurgitant_orifice.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "mvtwin/core/annulus_plane.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/triangle_bvh.h"

namespace mvtwin {

std::string_view mr_grade_name(MrGrade g) {
  switch (g) {
    case MrGrade::kNone:
      return "none";
    case MrGrade::kMild:
      return "mild";
    case MrGrade::kModerate:
      return "moderate";
    case MrGrade::kSevere:
      return "severe";
  }
  return "unknown";
}

MrGrade mr_grade_of(double eroa_mm2) {
  if (!(eroa_mm2 >= 1.0)) return MrGrade::kNone;
  if (eroa_mm2 < 20.0) return MrGrade::kMild;
  if (eroa_mm2 < 40.0) return MrGrade::kModerate;
  return MrGrade::kSevere;
}

bool OrificeOptions::is_valid(std::string* error) const {
  if (!(seal_mm >= 0 && seal_mm <= 5)) {
    *error = "orifice seal_mm must be in [0, 5] mm";
    return false;
  }
  if (!(contraction_coefficient > 0 && contraction_coefficient <= 1)) {
    *error = "orifice contraction coefficient must be in (0, 1]";
    return false;
  }
  if (!(central_fraction > 0 && central_fraction <= 1)) {
    *error = "orifice central fraction must be in (0, 1]";
    return false;
  }
  for (const auto& [b, e] : blocked) {
    if (!(b >= 0 && e <= 1 && b <= e)) {
      *error = "orifice: a blocked stretch must satisfy 0 <= begin <= end <= 1";
      return false;
    }
  }
  return true;
}

namespace {

/// The boundary of one leaflet: its atrial triangles and, with the ventricular surface, its
/// ventricular triangles and the rim between the two free edges.
TriangleMesh leaflet_mesh(const LeafletGrid& la, const LeafletGrid* lv, bool anterior) {
  const TriangleMesh all = la.triangulate();
  const Eigen::VectorXi tags = la.triangle_tags();
  const int want = static_cast<int>(anterior ? LeafletTag::kAnterior : LeafletTag::kPosterior);
  std::vector<Eigen::Vector3i> faces;
  for (Eigen::Index k = 0; k < tags.size(); ++k)
    if (tags[k] == want) faces.emplace_back(all.F.row(k).transpose());
  TriangleMesh m;
  const Eigen::Index n = all.V.rows();
  if (lv) {
    m.V.resize(2 * n, 3);
    m.V.topRows(n) = all.V;
    m.V.bottomRows(n) = lv->points();
    const size_t na = faces.size();
    for (size_t k = 0; k < na; ++k) faces.push_back(faces[k] + Eigen::Vector3i::Constant(n));
    const int U = la.ures(), last = (la.vres() - 1) * U;
    for (int u = 0; u < U; ++u) {
      if (la.column_tag(u) != static_cast<LeafletTag>(want)) continue;
      const int a = last + u, b = last + (u + 1) % U;
      faces.emplace_back(a, b, b + static_cast<int>(n));
      faces.emplace_back(a, b + static_cast<int>(n), a + static_cast<int>(n));
    }
  } else {
    m.V = all.V;
  }
  m.F.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (size_t k = 0; k < faces.size(); ++k)
    m.F.row(static_cast<Eigen::Index>(k)) = faces[k].transpose();
  return m;
}

/// One leaflet's side of the slit: its columns in order along the coaptation line.
struct Side {
  bool anterior = true;
  std::vector<int> u;              // grid columns, commissure to commissure
  std::vector<double> x;           // position along the line
  std::vector<int> v_min;          // row of the narrowest gap
  std::vector<double> gap;         // narrowest gap, mm
  std::vector<Eigen::Vector3d> a;  // the column's point there
  std::vector<Eigen::Vector3d> b;  // the other leaflet's closest point
  Eigen::MatrixXd d;               // distance of every point (column index, v) to the other leaflet
};

Side measure_side(const LeafletGrid& g, const LeafletGrid* lv, bool anterior,
                  const TriangleBvh& other) {
  const int U = g.ures(), V = g.vres(), half = U / 2;
  Side s;
  s.anterior = anterior;
  for (int k = 0; k <= half; ++k) {
    // Anterior column k and posterior column U - k stand at the same place along the line
    // (each leaflet's columns are spaced evenly in annulus arc length).
    s.u.push_back(anterior ? k : (U - k) % U);
    s.x.push_back(static_cast<double>(k) / half);
  }
  const int n = static_cast<int>(s.u.size());
  s.d.resize(n, V);
  for (int i = 0; i < n; ++i) {
    double best = std::numeric_limits<double>::infinity();
    int best_v = 0;
    TriangleBvh::Hit best_hit;
    Eigen::Vector3d best_a;
    for (int v = 0; v < V; ++v) {
      const TriangleBvh::Hit h = other.closest(g.at(s.u[i], v));
      s.d(i, v) = h.distance;
      if (h.distance < best) {
        best = h.distance;
        best_v = v;
        best_hit = h;
        best_a = g.at(s.u[i], v);
      }
      if (lv) {  // the column's ventricular side, too
        const TriangleBvh::Hit hv = other.closest(lv->at(s.u[i], v));
        s.d(i, v) = std::min(s.d(i, v), hv.distance);
        if (hv.distance < best) {
          best = hv.distance;
          best_v = v;
          best_hit = hv;
          best_a = lv->at(s.u[i], v);
        }
      }
    }
    s.v_min.push_back(best_v);
    s.gap.push_back(best);
    s.a.push_back(best_a);
    s.b.push_back(best_hit.point);
  }
  return s;
}

/// Column spacing between neighbours i and i + 1 along the line: the distance between the two
/// columns at the rows of their narrowest gaps (averaged over both rows).
double spacing(const LeafletGrid& g, const Side& s, int i) {
  double len = 0;
  for (const int v : {s.v_min[i], s.v_min[i + 1]})
    len += 0.5 * (g.at(s.u[i + 1], v) - g.at(s.u[i], v)).norm();
  return len;
}

struct OpenPiece {
  double x0, x1, area, length, max_gap;
};

/// The open pieces of one side, merged where they touch. Where a piece reaches into a stretch a
/// device fills (the seal crossing interpolated past the device's edge, or a device narrower
/// than the column spacing), the stretch is cut out of it.
std::vector<OpenPiece> open_pieces(const LeafletGrid& g, const Side& s, double seal,
                                   const std::vector<std::pair<double, double>>& blocked) {
  std::vector<OpenPiece> out;
  for (size_t i = 0; i + 1 < s.gap.size(); ++i) {
    const double g0 = s.gap[i], g1 = s.gap[i + 1];
    if (g0 <= seal && g1 <= seal) continue;
    const double dl = spacing(g, s, static_cast<int>(i));
    const double x0 = s.x[i], x1 = s.x[i + 1];
    // The open stretch of the segment (the gap linear between the columns).
    double a = x0, b = x1;
    if (g0 <= seal || g1 <= seal) {
      const double hi = std::max(g0, g1), lo = std::min(g0, g1);
      const double f = (hi - seal) / (hi - lo);
      if (g0 > seal)
        b = x0 + f * (x1 - x0);
      else
        a = x1 - f * (x1 - x0);
    }
    std::vector<std::pair<double, double>> parts{{a, b}};
    for (const auto& [c0, c1] : blocked) {
      std::vector<std::pair<double, double>> kept;
      for (const auto& [p0, p1] : parts) {
        if (c1 <= p0 || c0 >= p1) {
          kept.emplace_back(p0, p1);
          continue;
        }
        if (c0 > p0) kept.emplace_back(p0, c0);
        if (c1 < p1) kept.emplace_back(c1, p1);
      }
      parts = std::move(kept);
    }
    auto gap_at = [&](double x) { return g0 + (g1 - g0) * (x - x0) / (x1 - x0); };
    for (const auto& [p0, p1] : parts) {
      if (!(p1 > p0)) continue;
      const double fr = (p1 - p0) / (x1 - x0);
      OpenPiece p{p0, p1, 0.5 * (gap_at(p0) + gap_at(p1)) * fr * dl, fr * dl,
                  std::max(gap_at(p0), gap_at(p1))};
      if (!out.empty() && out.back().x1 >= p.x0 - 1e-12) {
        OpenPiece& q = out.back();
        q.x1 = p.x1;
        q.area += p.area;
        q.length += p.length;
        q.max_gap = std::max(q.max_gap, p.max_gap);
      } else {
        out.push_back(p);
      }
    }
  }
  return out;
}

double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace

RegurgitantOrifice measure_regurgitant_orifice(const LeafletGrid& g, const OrificeOptions& opt,
                                               const LeafletGrid* lv) {
  if (std::string why; !opt.is_valid(&why)) throw Error(why);
  if (g.ures() < 8 || g.vres() < 3) throw Error("regurgitant orifice: the grid is too coarse");
  if (!g.points().allFinite()) throw Error("regurgitant orifice: non-finite surface coordinates");
  if (lv && (lv->ures() != g.ures() || lv->vres() != g.vres()))
    throw Error("regurgitant orifice: the ventricular surface is on another grid");
  if (lv && !lv->points().allFinite())
    throw Error("regurgitant orifice: non-finite ventricular surface coordinates");
  const TriangleBvh anterior_bvh(leaflet_mesh(g, lv, true)),
      posterior_bvh(leaflet_mesh(g, lv, false));
  const Side sides[2] = {measure_side(g, lv, true, posterior_bvh),
                         measure_side(g, lv, false, anterior_bvh)};
  const double seal = opt.seal_mm;

  RegurgitantOrifice r;
  r.options = opt;
  for (const Side& s : sides) {
    for (size_t i = 0; i < s.gap.size(); ++i)
      r.columns.push_back({s.x[i], s.gap[i], s.a[i], s.b[i], s.anterior});
  }

  // Openings: the union along the line of both sides' open pieces; each side's area and length
  // count half (both leaflets see the same slit, from either side).
  std::vector<OpenPiece> pieces;
  for (const Side& s : sides) {
    for (OpenPiece p : open_pieces(g, s, seal, opt.blocked)) {
      p.area *= 0.5;
      p.length *= 0.5;
      pieces.push_back(p);
    }
  }
  std::sort(pieces.begin(), pieces.end(),
            [](const OpenPiece& a, const OpenPiece& b) { return a.x0 < b.x0; });
  for (const OpenPiece& p : pieces) {
    if (!r.openings.empty() && p.x0 <= r.openings.back().end + 1e-12) {
      Opening& o = r.openings.back();
      o.end = std::max(o.end, p.x1);
      o.area_mm2 += p.area;
      o.length_mm += p.length;
      o.max_gap_mm = std::max(o.max_gap_mm, p.max_gap);
    } else {
      r.openings.push_back({p.area, p.x0, p.x1, p.length, p.max_gap});
    }
  }
  std::sort(r.openings.begin(), r.openings.end(),
            [](const Opening& a, const Opening& b) { return a.area_mm2 > b.area_mm2; });
  for (const Opening& o : r.openings) r.aroa_mm2 += o.area_mm2;
  r.eroa_mm2 = opt.contraction_coefficient * r.aroa_mm2;
  r.grade = mr_grade_of(r.eroa_mm2);

  // Coaptation over the central anterior columns.
  const Side& ant = sides[0];
  const AnnulusPlane plane = least_squares_plane(g.points().topRows(g.ures()));
  const double lo = 0.5 * (1.0 - opt.central_fraction), hi = 0.5 * (1.0 + opt.central_fraction);
  std::vector<double> lengths, depths;
  int looked = 0;
  for (size_t i = 0; i < ant.x.size(); ++i) {
    if (ant.x[i] < lo - 1e-12 || ant.x[i] > hi + 1e-12) continue;
    ++looked;
    double len = 0;
    bool first_found = false;
    Eigen::Vector3d first;
    for (int v = 0; v + 1 < g.vres(); ++v) {
      const double d0 = ant.d(i, v), d1 = ant.d(i, v + 1);
      const Eigen::Vector3d p0 = g.at(ant.u[i], v), p1 = g.at(ant.u[i], v + 1);
      const bool in0 = d0 <= seal, in1 = d1 <= seal;
      double f0 = 0, f1 = 0;  // the sealed part of the segment, as fractions from p0
      if (in0 && in1) {
        f1 = 1;
      } else if (in0 != in1) {
        const double f = (d0 - seal) / (d0 - d1);  // where the distance crosses the seal
        if (in0) {
          f1 = f;
        } else {
          f0 = f;
          f1 = 1;
        }
      } else {
        continue;
      }
      len += (f1 - f0) * (p1 - p0).norm();
      if (!first_found) {
        first_found = true;
        first = p0 + f0 * (p1 - p0);
      }
    }
    if (len > 0) {
      lengths.push_back(len);
      depths.push_back(-plane.signed_distance(first));
    }
  }
  r.coapting_fraction = looked > 0 ? static_cast<double>(lengths.size()) / looked : 0.0;
  r.coaptation_length_mm = lengths.empty() ? 0.0 : median(lengths);
  r.coaptation_depth_mm = median(depths);
  return r;
}

}  // namespace mvtwin
