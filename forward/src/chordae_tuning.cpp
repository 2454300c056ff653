#include "mvtwin/forward/chordae_tuning.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "mvtwin/core/annulus_plane.h"
#include "mvtwin/core/error.h"

namespace mvtwin::forward {

namespace {

constexpr int kInsertionSites = 28;  // the paper's marginal insertion sites

/// Periodic distance between two insertion sites in [0, 1).
double site_distance(double a, double b) {
  const double d = std::abs(a - b);
  return std::min(d, 1.0 - d);
}

}  // namespace

std::string ChordaeTuningOptions::problem() const {
  std::ostringstream os;
  if (!(iterations >= 0 && iterations <= 50))
    os << "iterations must be in [0, 50]";
  else if (!(gain > 0 && gain <= 10))
    os << "gain must be in (0, 10]";
  else if (!(max_step_mm > 0 && max_step_mm <= 10))
    os << "max_step_mm must be in (0, 10]";
  else if (!(reach_sites > 0 && reach_sites <= 14))
    os << "reach_sites must be in (0, 14]";
  else if (!(shortest > 0 && shortest <= 1))
    os << "shortest must be in (0, 1]";
  else if (!(longest >= 1 && longest <= 5))
    os << "longest must be in [1, 5]";
  return os.str();
}

std::vector<double> chordae_length_changes(const RegurgitantOrifice& orifice,
                                           const std::vector<ChordaLength>& lengths,
                                           const Eigen::Vector3d& atrial,
                                           const ChordaeTuningOptions& o) {
  std::vector<double> delta(lengths.size(), 0.0);
  const double width = o.reach_sites / kInsertionSites;
  const double seal = orifice.options.seal_mm;
  for (const ColumnGap& c : orifice.columns) {
    if (!(c.gap_mm > seal)) continue;
    // The other leaflet above this one: this leaflet must rise, so its chordae lengthen.
    const bool other_above = (c.b - c.a).dot(atrial) > 0;
    // Along the line 0 is the anterolateral commissure; the anterior leaflet's insertion sites
    // run over [0, 0.5] from it, the posterior leaflet's back from 1 to 0.5.
    const double s = c.anterior ? c.position / 2 : 1.0 - c.position / 2;
    const double step =
        (other_above ? 1.0 : -1.0) * o.gain * std::min(c.gap_mm - seal, o.max_step_mm);
    for (size_t j = 0; j < lengths.size(); ++j) {
      const double sj = lengths[j].s;
      const bool commissure = sj == 0.0 || sj == 0.5;
      const bool same_leaflet = commissure || ((sj < 0.5) == c.anterior);
      const double ds = site_distance(sj, s);
      if (same_leaflet && ds < width) delta[j] += step * (1.0 - ds / width);
    }
  }
  return delta;
}

ChordaeTuning tune_marginal_chordae(const ValveSequence& sequence,
                                    const ValveParameters& parameters,
                                    const ChordaeTuningOptions& options) {
  if (const std::string p = options.problem(); !p.empty()) {
    throw Error("chordae tuning: " + p);
  }
  if (sequence.marginal_chordae_lengths.empty()) {
    throw Error(
        "chordae tuning: the valve has no marginal chordae lengths to tune "
        "(/sequence/marginal_chordae_lengths)");
  }
  if (const std::string p = sequence.chordae_lengths_problem(); !p.empty()) {
    throw Error("chordae tuning: " + p);
  }
  ValveSequence seq = sequence;
  const std::vector<ChordaLength> start = sequence.marginal_chordae_lengths;
  // The end-diastolic annulus does not move with the chordae: one plane for every iteration.
  const Eigen::Vector3d atrial =
      least_squares_plane(sequence.frames[sequence.end_diastole].annulus).normal;
  ChordaeTuning out;
  out.lengths = start;
  double best_eroa = std::numeric_limits<double>::infinity();
  for (int it = 0; it <= options.iterations; ++it) {
    const ClosureResult r = simulate_closure(seq, parameters, options.simulation);
    if (!r.summary.converged() || !r.orifice) {
      out.eroa_mm2.push_back(std::numeric_limits<double>::quiet_NaN());
      std::ostringstream os;
      os << "closure " << it
         << " failed: " << (r.summary.converged() ? "no orifice measured" : r.summary.reason);
      out.failure = os.str();
      if (options.progress) options.progress(it, out.eroa_mm2.back());
      break;
    }
    const double eroa = r.orifice->eroa_mm2;
    out.eroa_mm2.push_back(eroa);
    if (options.progress) options.progress(it, eroa);
    if (eroa < best_eroa) {
      best_eroa = eroa;
      out.best = it;
      out.lengths = seq.marginal_chordae_lengths;
    }
    if (it == options.iterations) break;
    const std::vector<double> d =
        chordae_length_changes(*r.orifice, seq.marginal_chordae_lengths, atrial, options);
    if (std::all_of(d.begin(), d.end(), [](double x) { return x == 0.0; })) break;  // sealed
    for (size_t j = 0; j < d.size(); ++j) {
      ChordaLength& c = seq.marginal_chordae_lengths[j];
      c.length_mm = std::clamp(c.length_mm + d[j], options.shortest * start[j].length_mm,
                               options.longest * start[j].length_mm);
    }
  }
  return out;
}

int tuning_edition(const Patient& p) {
  if (!p.truth) return 0;
  bool tuned = false;
  for (const auto& [quantity, v] : p.truth->anatomy) {
    if (quantity == "chordae_tuning_edition") return static_cast<int>(v);
    tuned = tuned || quantity == "chordae_tuning_eroa_mm2";
  }
  return tuned ? 1 : 0;
}

bool is_tunable_normal_valve(const Patient& p) {
  return p.synthetic && p.truth && p.truth->pathology == Pathology::kNormal &&
         !p.sequence.marginal_chordae_lengths.empty() && !p.sequence.has_closed_leaflets();
}

ChordaeTuning tune_normal_virtual_patient(Patient* p, const ChordaeTuningOptions& options) {
  if (!p->synthetic || !p->truth) {
    throw Error("chordae tuning needs a virtual patient (its hidden parameters close the valve)");
  }
  if (p->truth->pathology != Pathology::kNormal) {
    throw Error("a " + std::string(pathology_name(p->truth->pathology)) +
                " valve's leak is its pathology; chordae tuning sizes a normal valve's chordae");
  }
  // Closing frames simulated with the chordae as they are would no longer be this valve's.
  if (p->sequence.has_closed_leaflets()) {
    throw Error(
        "its closing frames were simulated with the chordae it has; tune a patient made "
        "without them (mvtwin phantom without --simulate-closure)");
  }
  ChordaeTuning t = tune_marginal_chordae(p->sequence, p->truth->parameters, options);
  if (std::isnan(t.kept_eroa_mm2())) return t;
  p->sequence.marginal_chordae_lengths = t.lengths;
  auto& anatomy = p->truth->anatomy;
  std::erase_if(anatomy, [](const auto& q) { return q.first.rfind("chordae_tuning_", 0) == 0; });
  anatomy.emplace_back("chordae_tuning_edition", kChordaeTuningEdition);
  anatomy.emplace_back("chordae_tuning_iterations", t.best);
  anatomy.emplace_back("chordae_tuning_eroa_before_mm2", t.eroa_mm2.front());
  anatomy.emplace_back("chordae_tuning_eroa_mm2", t.kept_eroa_mm2());
  const std::string tuned = "; marginal chordae tuned to close (chordae tuning edition " +
                            std::to_string(kChordaeTuningEdition) + ")";
  // A second tuning replaces the first one's note (up to its closing parenthesis).
  std::string& source = p->provenance.source;
  if (const size_t at = source.find("; marginal chordae tuned to close"); at != std::string::npos) {
    const size_t close = source.find(')', at);
    source.erase(at, close == std::string::npos ? std::string::npos : close + 1 - at);
  }
  source += tuned;
  return t;
}

}  // namespace mvtwin::forward
