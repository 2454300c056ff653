#include "mvtwin/inverse/clip_prediction.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "mvtwin/core/error.h"
#include "parallel_indices.h"

namespace mvtwin::inverse {

forward::ClipOptions clip_options(const ClipSite& s) {
  forward::ClipOptions c;
  c.anterior_s = 0.5 * s.position;
  c.posterior_s = 1.0 - 0.5 * s.position;
  c.anterior_t = c.posterior_t = s.depth;
  return c;
}

std::vector<ClipSite> parse_clip_sites(const std::string& text) {
  std::vector<ClipSite> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ';')) {
    if (item.find_first_not_of(" \t") == std::string::npos) continue;
    ClipSite s;
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
  return q;
}

std::vector<ClipScenario> simulate_clips(const Patient& patient, const ValveParameters& par,
                                         const forward::ClosureOptions& options,
                                         const std::vector<std::vector<ClipSite>>& candidates,
                                         int jobs) {
  std::vector<ClipScenario> out(candidates.size());
  parallel_indices(candidates.size(), jobs, [&](size_t i) {
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
  return out;
}

std::vector<std::vector<ClipSite>> clip_candidates(bool pairs) {
  std::vector<double> pos;
  for (int k = 2; k <= 8; ++k) pos.push_back(0.1 * k);
  std::vector<std::vector<ClipSite>> out;
  for (double p : pos) out.push_back({ClipSite{p, 1.0}});
  if (pairs) {
    for (size_t i = 0; i < pos.size(); ++i)
      for (size_t j = i + 1; j < pos.size(); ++j)
        if (pos[j] - pos[i] >= 0.2 - 1e-9)
          out.push_back({ClipSite{pos[i], 1.0}, ClipSite{pos[j], 1.0}});
  }
  return out;
}

void rank_by_residual_orifice(std::vector<ClipScenario>* s) {
  std::stable_sort(s->begin(), s->end(), [](const ClipScenario& a, const ClipScenario& b) {
    if (a.quality.converged != b.quality.converged) return a.quality.converged;
    return a.quality.orifice.eroa_mm2 < b.quality.orifice.eroa_mm2;
  });
}

}  // namespace mvtwin::inverse
