#include <Eigen/Geometry>

#include "mvtwin/core/valve_sequence.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "mvtwin/core/error.h"

namespace mvtwin {

using Curve = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

Curve resample_closed_curve(const Eigen::Ref<const Curve>& curve, int m) {
  const int n = static_cast<int>(curve.rows());
  Curve out(m, 3);
  auto p = [&](int i) -> Eigen::Vector3d { return curve.row(((i % n) + n) % n).transpose(); };
  for (int k = 0; k < m; ++k) {
    const double x = static_cast<double>(k) * n / m;
    const int i = static_cast<int>(std::floor(x));
    const double f = x - i, f2 = f * f, f3 = f2 * f;
    out.row(k) = ((-0.5 * f3 + f2 - 0.5 * f) * p(i - 1) + (1.5 * f3 - 2.5 * f2 + 1.0) * p(i) +
                  (-1.5 * f3 + 2.0 * f2 + 0.5 * f) * p(i + 1) + (0.5 * f3 - 0.5 * f2) * p(i + 2))
                     .transpose();
  }
  return out;
}

ChordaeRupture marginal_chorda_rupture(int k, int n) {
  return {std::max(0.0, (k - 0.5) / n), std::min(1.0, (k + 0.5) / n)};
}

double ValveSequence::marginal_chorda_length_at(double s) const {
  const std::vector<ChordaLength>& c = marginal_chordae_lengths;
  if (c.empty()) return std::numeric_limits<double>::quiet_NaN();
  if (c.size() == 1) return c.front().length_mm;
  s -= std::floor(s);
  // The first site at or after s; the segment before it wraps round the annulus.
  const auto hi = std::lower_bound(c.begin(), c.end(), s,
                                   [](const ChordaLength& a, double x) { return a.s < x; });
  const ChordaLength& b = hi == c.end() ? c.front() : *hi;
  const ChordaLength& a = hi == c.begin() ? c.back() : *(hi - 1);
  double span = b.s - a.s, off = s - a.s;
  if (span <= 0.0) span += 1.0;
  if (off < 0.0) off += 1.0;
  return a.length_mm + (b.length_mm - a.length_mm) * (off / span);
}

void ValveSequence::keep_chordae_anatomy(const ValveSequence& known) {
  if (ruptured_chordae.empty()) ruptured_chordae = known.ruptured_chordae;
  if (marginal_chordae_lengths.empty()) marginal_chordae_lengths = known.marginal_chordae_lengths;
}

std::string ValveSequence::chordae_lengths_problem() const {
  for (size_t i = 0; i < marginal_chordae_lengths.size(); ++i) {
    const ChordaLength& c = marginal_chordae_lengths[i];
    if (!(c.s >= 0.0 && c.s < 1.0) || (i > 0 && !(c.s > marginal_chordae_lengths[i - 1].s)))
      return "marginal chordae lengths need sites increasing in [0, 1), got s = " +
             std::to_string(c.s) + " at entry " + std::to_string(i);
    if (!(c.length_mm > 0.0) || !std::isfinite(c.length_mm))
      return "the marginal chorda length at s = " + std::to_string(c.s) +
             " must be positive and finite, got " + std::to_string(c.length_mm) + " mm";
  }
  return "";
}

void ValveSequence::validate(const char* what) const {
  const std::string w(what);
  auto fail = [&](const std::string& msg) { throw Error(w + ": " + msg); };
  if (frames.empty()) fail("the sequence has no frames");
  if (ures < 8 || ures % 2 != 0) fail("ures must be even and >= 8, got " + std::to_string(ures));
  if (vres < 3) fail("vres must be >= 3, got " + std::to_string(vres));
  for (const ChordaeRupture& r : ruptured_chordae) {
    if (!r.is_valid())
      fail("a chordae rupture must have 0 <= s_begin < s_end <= 1, got [" +
           std::to_string(r.s_begin) + ", " + std::to_string(r.s_end) + ")");
  }
  if (const std::string problem = chordae_lengths_problem(); !problem.empty()) fail(problem);
  const int n = num_frames();
  if (end_diastole < -1 || end_diastole >= n) {
    fail("end_diastole index " + std::to_string(end_diastole) + " is outside 0.." +
         std::to_string(n - 1));
  }
  if (first_closed < -1 || first_closed >= n) {
    fail("first_closed index " + std::to_string(first_closed) + " is outside 0.." +
         std::to_string(n - 1));
  }
  if (end_diastole >= 0 && first_closed >= 0 && first_closed <= end_diastole) {
    fail("first_closed (" + std::to_string(first_closed) + ") must come after end_diastole (" +
         std::to_string(end_diastole) + ")");
  }
  for (int f = 0; f < n; ++f) {
    const ValveFrame& fr = frames[f];
    const std::string at = "frame " + std::to_string(f) + ": ";
    if (!std::isfinite(fr.time_s)) fail(at + "time is not finite");
    if (f > 0 && !(fr.time_s > frames[f - 1].time_s)) {
      fail(at + "times are not strictly increasing (" + std::to_string(frames[f - 1].time_s) +
           " s then " + std::to_string(fr.time_s) + " s)");
    }
    for (int l = 0; l < kNumLandmarks; ++l) {
      if (fr.landmark_observed[l] && !fr.landmarks[l].allFinite()) {
        fail(at + "landmark " + std::string(kLandmarkNames[l]) +
             " is marked observed but is not finite");
      }
    }
    if (fr.annulus.rows() != ures) {
      fail(at + "annulus has " + std::to_string(fr.annulus.rows()) +
           " points, expected ures = " + std::to_string(ures));
    }
    if (!fr.annulus.allFinite()) fail(at + "annulus has a non-finite coordinate");
    if (fr.la_surface) {
      const LeafletGrid& g = *fr.la_surface;
      if (g.ures() != ures || g.vres() != vres) {
        fail(at + "surface grid is " + std::to_string(g.ures()) + "x" + std::to_string(g.vres()) +
             ", expected " + std::to_string(ures) + "x" + std::to_string(vres));
      }
      for (Eigen::Index r = 0; r < g.points().rows(); ++r) {
        if (!g.points().row(r).allFinite()) {
          fail(at + "surface point (u=" + std::to_string(r % ures) +
               ", v=" + std::to_string(r / ures) + ") is not finite");
        }
      }
      const double gap = (g.points().topRows(ures) - fr.annulus).rowwise().norm().maxCoeff();
      if (gap > 1e-6) {
        fail(at + "annulus differs from the surface's v=0 row by " + std::to_string(gap) + " mm");
      }
    }
  }
}

ValveSequence ValveSequence::resampled(int new_ures, int new_vres) const {
  ValveSequence out = *this;
  out.ures = new_ures;
  out.vres = new_vres;
  for (ValveFrame& fr : out.frames) {
    if (fr.la_surface) {
      fr.la_surface = fr.la_surface->resampled(new_ures, new_vres);
      fr.annulus = fr.la_surface->points().topRows(new_ures);
    } else {
      fr.annulus = resample_closed_curve(fr.annulus, new_ures);
    }
  }
  return out;
}

std::string ValveSequence::assumed_landmarks() const {
  std::string out;
  for (int l = 0; l < kNumLandmarks; ++l) {
    bool any = false;
    for (const ValveFrame& f : frames)
      any = any || (f.landmark_observed[l] && f.landmark_assumed[l]);
    if (any) out += (out.empty() ? "" : ", ") + std::string(kLandmarkNames[l]);
  }
  return out;
}

}  // namespace mvtwin
