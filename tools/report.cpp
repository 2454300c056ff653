// The reports of tools/report.h.
#include "report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "mvtwin/core/annulus_measures.h"
#include "mvtwin/core/annulus_plane.h"
#include "mvtwin/core/units.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/inverse/outcome_uncertainty.h"

namespace mvtwin::tools {

std::string fixed(double v, int precision) {
  if (std::isnan(v)) return "n/a";
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", precision, v);
  return b;
}

void print_assumed(const Patient& p, std::ostream& os) {
  const std::string a = p.sequence.assumed_landmarks();
  if (!a.empty())
    os << "ASSUMED   " << a
       << ": estimated from published anatomy, not observed (they drive the closure)\n";
}

void print_simulation_record(const SimulationRecord& r, std::ostream& os) {
  os << "simulation of " << r.patient_id << (r.synthetic ? "   [SYNTHETIC: virtual patient]" : "")
     << "  (" << r.patient_file << ")\n";
  os << "made by   mvtwin " << r.provenance.version << ", " << r.provenance.created_utc << "\n";
  os << "command   " << r.provenance.command << "\n";
  if (!r.provenance.source.empty()) os << "input     " << r.provenance.source << "\n";
  os << "status    " << r.status << (r.reason.empty() ? "" : ": " + r.reason) << "\n";
  os << "summary  ";
  for (const auto& [k, v] : r.summary) os << " " << k << "=" << v;
  os << "\nparameters";
  r.parameters.for_each([&](const std::string& n, double v, const char* unit) {
    os << " " << n << "=" << v << (std::string(unit) == "1" ? "" : " " + std::string(unit));
  });
  os << "\noptions  ";
  for (const auto& [k, v] : r.options) os << " " << k << "=" << v;
  os << "\nsamples   " << r.time_s.size() << " on a " << r.la_surface.front().ures() << " x "
     << r.la_surface.front().vres() << " grid\n";
  for (size_t i = 0; i < r.time_s.size(); ++i) {
    os << "  t = " << fixed(r.time_s[i], 2) << " s (observed " << fixed(r.observed_time_s[i], 3)
       << " s): tips " << fixed(r.anterior_tip_mm[i]) << " / " << fixed(r.posterior_tip_mm[i])
       << " mm, seen through " << fixed(r.orifice_area_mm2[i], 1) << " of "
       << fixed(r.annulus_area_mm2[i], 0) << " mm^2\n";
  }
  if (r.orifice) os << "closed    " << orifice_line(*r.orifice) << "\n";
  double smax = 0, vmax = 0;
  for (Eigen::Index e = 0; e < r.element_strain.size(); ++e) {
    smax = std::max(smax, r.element_strain[e]);
    vmax = std::max(vmax, r.element_stress_mpa[e]);
  }
  os << "end state " << r.mesh.T.rows() << " tetrahedra; largest principal strain "
     << fixed(smax, 3) << ", largest von Mises stress " << fixed(vmax * 1000.0, 1) << " kPa\n";
}

void print_patient(const Patient& p, std::ostream& os) {
  const ValveSequence& s = p.sequence;
  os << "patient   " << p.id << (p.synthetic ? "   [SYNTHETIC: virtual patient]" : "") << "\n";
  print_assumed(p, os);
  os << "source    " << p.provenance.source << "\n";
  os << "made by   mvtwin " << p.provenance.version << ", " << p.provenance.created_utc
     << (p.provenance.seed ? ", seed " + std::to_string(p.provenance.seed) : "") << "\n";
  os << "command   " << p.provenance.command << "\n";
  if (!p.import_report.empty()) {
    std::istringstream lines(p.import_report);
    for (std::string l; std::getline(lines, l);) os << "import    " << l << "\n";
  }
  int observed = 0;
  for (const auto& f : s.frames) observed += f.la_surface.has_value();
  os << "sequence  " << s.num_frames() << " frames, t = " << fixed(s.frames.front().time_s, 3)
     << " .. " << fixed(s.frames.back().time_s, 3) << " s; grid ures=" << s.ures
     << " vres=" << s.vres << "; leaflets observed in " << observed << " frames\n";
  os << "phases    end-diastole = "
     << (s.end_diastole >= 0 ? "frame " + std::to_string(s.end_diastole) : "unknown")
     << ", first closed = "
     << (s.first_closed >= 0 ? "frame " + std::to_string(s.first_closed) : "unknown");
  if (s.end_diastole >= 0 && s.first_closed >= 0) {
    os << " (closure "
       << fixed(s.frames[s.first_closed].time_s - s.frames[s.end_diastole].time_s, 3) << " s)";
  }
  os << "\n";
  auto frame_report = [&](int f, const char* label) {
    if (f < 0) return;
    const ValveFrame& fr = s.frames[f];
    const AnnulusMeasures m = annulus_measures(fr);
    os << label << " (frame " << f << ")\n";
    os << "  annulus   AP " << fixed(m.ap_diameter_mm, 1) << " mm, AL-PM "
       << fixed(m.alpm_diameter_mm, 1) << " mm, commissural width "
       << fixed(m.commissural_width_mm, 1) << " mm, intertrigonal " << fixed(m.intertrigonal_mm, 1)
       << " mm\n";
    os << "            perimeter " << fixed(m.perimeter_mm, 1) << " mm, 3D area "
       << fixed(units::mm2_to_cm2(m.area_3d_mm2)) << " cm^2, height " << fixed(m.height_mm, 1)
       << " mm (" << fixed(100 * m.height_mm / m.commissural_width_mm, 1)
       << " % of commissural width), arcs ant/post " << fixed(m.anterior_arc_mm, 1) << "/"
       << fixed(m.posterior_arc_mm, 1) << " mm\n";
    if (fr.la_surface) {
      const double area = fr.la_surface->triangulate().area();
      os << "  leaflets  AL length " << fixed(fr.la_surface->radial_length_at(0.25), 1)
         << " mm, PL length " << fixed(fr.la_surface->radial_length_at(0.75), 1)
         << " mm, LA surface area " << fixed(units::mm2_to_cm2(area)) << " cm^2 ("
         << fixed(area / m.area_3d_mm2) << " x annulus)\n";
      const TipToAnnulusPlane t = tip_to_annulus_plane(fr);
      os << "  tips      to annulus plane: anterior " << fixed(t.anterior_mm, 1)
         << " mm, posterior " << fixed(t.posterior_mm, 1) << " mm (+ = atrial; plane from "
         << (t.plane_from_landmarks ? "trigones + posterior mid-point" : "least squares") << ")\n";
    } else {
      os << "  leaflets  not observed in this frame\n";
    }
  };
  frame_report(s.end_diastole, "end-diastole");
  frame_report(s.first_closed, "first closed");
  for (const ChordaeRupture& r : s.ruptured_chordae) {
    os << "chordae   ruptured: the marginal chordae inserting at s in [" << fixed(r.s_begin, 3)
       << ", " << fixed(r.s_end, 3) << ") ("
       << (r.s_end <= 0.5     ? "anterior"
           : r.s_begin >= 0.5 ? "posterior"
                              : "both")
       << " leaflet)\n";
  }
  if (!s.marginal_chordae_lengths.empty()) {
    double lo = 1e9, hi = 0.0;
    for (const ChordaLength& c : s.marginal_chordae_lengths) {
      lo = std::min(lo, c.length_mm);
      hi = std::max(hi, c.length_mm);
    }
    os << "chordae   marginal lengths given at " << s.marginal_chordae_lengths.size() << " sites, "
       << fixed(lo, 1) << "-" << fixed(hi, 1)
       << " mm (the model's marginal rest lengths start from them)\n";
  }
  if (s.end_diastole < 0 && s.first_closed < 0) frame_report(0, "frame 0");
  if (!p.images.empty()) {
    const auto& im = p.images.front();
    os << "images    " << p.images.size() << " volume(s), " << im.size[0] << "x" << im.size[1]
       << "x" << im.size[2] << " voxels of " << fixed(im.spacing[0]) << "x" << fixed(im.spacing[1])
       << "x" << fixed(im.spacing[2]) << " mm\n";
  }
  if (p.truth) {
    const VirtualTruth& t = *p.truth;
    os << "hidden    pathology " << pathology_name(t.pathology) << "; ";
    t.parameters.for_each([&](const std::string& n, double v, const char* unit) {
      if (n == "peak_pressure") {
        os << n << " " << fixed(units::mpa_to_mmhg(v), 1) << " mmHg";
      } else {
        os << n << " " << fixed(v, 3) << (std::string(unit) == "1" ? "" : std::string(" ") + unit)
           << "; ";
      }
    });
    os << "\n";
    os << "closed    " << t.closed_frames << "\n";
    if (t.closed_orifice) os << "          true " << orifice_line(*t.closed_orifice) << "\n";
  }
}

std::string orifice_line(const RegurgitantOrifice& o) {
  std::string s = "regurgitant orifice " + fixed(o.aroa_mm2, 1) + " mm^2 (EROA " +
                  fixed(o.eroa_mm2, 1) + " mm^2: " + std::string(mr_grade_name(o.grade)) + " MR";
  if (!o.openings.empty()) {
    s += "; " + std::to_string(o.openings.size()) + " opening" +
         (o.openings.size() == 1 ? "" : "s") + ":";
    for (const Opening& x : o.openings)
      s += " " + fixed(x.area_mm2, 1) + " at " + fixed(x.begin, 2) + "-" + fixed(x.end, 2);
  }
  s += "), coaptation " + fixed(o.coaptation_length_mm, 1) + " mm long";
  if (std::isfinite(o.coaptation_depth_mm))
    s += ", " + fixed(o.coaptation_depth_mm, 1) + " mm below the annulus";
  return s + " (sealed within " + fixed(o.options.seal_mm, 2) + " mm)";
}

nlohmann::json orifice_json(const RegurgitantOrifice& o) {
  nlohmann::json openings = nlohmann::json::array(), areas = nlohmann::json::array();
  for (const Opening& x : o.openings) {
    areas.push_back(x.area_mm2);
    openings.push_back({{"area_mm2", x.area_mm2},
                        {"begin", x.begin},
                        {"end", x.end},
                        {"length_mm", x.length_mm},
                        {"max_gap_mm", x.max_gap_mm}});
  }
  auto finite_or_null = [](double v) {
    return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
  };
  return {{"aroa_mm2", o.aroa_mm2},
          {"eroa_mm2", o.eroa_mm2},
          {"openings_mm2", areas},
          {"openings", openings},
          {"mr_grade", std::string(mr_grade_name(o.grade))},
          {"coaptation_length_mm", o.coaptation_length_mm},
          {"coaptation_depth_mm", finite_or_null(o.coaptation_depth_mm)},
          {"coapting_fraction", o.coapting_fraction},
          {"seal_mm", o.options.seal_mm},
          {"contraction_coefficient", o.options.contraction_coefficient}};
}

void print_closure(const forward::ClosureResult& r, std::ostream& os) {
  os << r.summary.brief_report() << "\n";
  for (const auto& s : r.samples) {
    os << "  t = " << fixed(s.time_s, 2) << " s: tips to annulus plane, anterior "
       << fixed(s.anterior_tip_mm) << " mm, posterior " << fixed(s.posterior_tip_mm)
       << " mm; seen through " << fixed(s.orifice_area_mm2, 1) << " of "
       << fixed(s.annulus_area_mm2, 0) << " mm^2 (" << s.orifice_components << " opening"
       << (s.orifice_components == 1 ? "" : "s") << "); closest contact "
       << fixed(s.min_contact_distance_mm, 2) << " mm\n";
  }
  if (!r.samples.empty()) {
    const auto& a = r.samples.front();
    const auto& b = r.samples.back();
    os << "closure: opening seen from the atrium along the annulus normal "
       << fixed(a.orifice_area_mm2, 1) << " -> " << fixed(b.orifice_area_mm2, 1)
       << " mm^2; closest contact " << fixed(r.summary.min_contact_distance_mm, 2) << " mm\n";
  }
  if (r.orifice) os << "closed valve: " << orifice_line(*r.orifice) << "\n";
  for (size_t c = 0; c < r.clip_gap_clipped_mm.size(); ++c) {
    os << "clip " << c + 1 << ": atrial surfaces " << fixed(r.clip_gap_clipped_mm[c], 2)
       << " mm apart after clipping";
    if (c < r.clip_gap_end_mm.size())
      os << ", " << fixed(r.clip_gap_end_mm[c], 2) << " mm at the end";
    os << "\n";
  }
}

void print_calibration(const CalibrationRecord& c, std::ostream& os) {
  os << "calibration of " << c.patient_id << (c.synthetic ? " [SYNTHETIC]" : "") << " by "
     << c.method << ": " << c.termination << "\n";
  if (!c.provenance.source.empty()) os << "  " << c.provenance.source << "\n";
  os << "  error " << fixed(c.error_before_mm, 3) << " -> " << fixed(c.error_after_mm, 3) << " mm; "
     << c.simulations << " simulations (" << c.failed_simulations << " failed, " << c.cache_hits
     << " from the cache), " << fixed(c.wall_s, 1) << " s\n";
  if (c.search_simulations > 0) {
    os << "  searched on a cheaper model (" << c.search_simulations
       << " of the simulations): " << fixed(c.search_error_before_mm, 3) << " -> "
       << fixed(c.search_error_after_mm, 3) << " mm there; " << c.refinement << "\n";
  }
  // sd: the data's alone; in bounds: with the parameter's bounds as a prior, what the clip
  // plan's intervals use (inverse::bounded_sd).
  const Eigen::VectorXd in_bounds = inverse::bounded_sd(c);
  os << "  parameter                                   start     fitted   +- sd  in bounds     "
     << (c.synthetic ? "truth" : "") << "\n";
  for (size_t i = 0; i < c.names.size(); ++i) {
    const auto k = static_cast<Eigen::Index>(i);
    char line[256];
    std::snprintf(line, sizeof line, "  %-40s %8s  %8s  %8s  %8s  %8s %s%s\n",
                  (c.names[i] + (c.units[i] == "1" ? "" : " [" + c.units[i] + "]")).c_str(),
                  fixed(c.start[k], 3).c_str(), fixed(c.fitted[k], 3).c_str(),
                  fixed(c.sd[k], 3).c_str(), fixed(in_bounds[k], 3).c_str(),
                  c.synthetic ? fixed(c.truth[k], 3).c_str() : "",
                  c.identified[i] ? "" : "  (not identified by the data)", "");
    os << line;
  }
  // The strongest trade-offs.
  for (Eigen::Index i = 0; i < c.correlation.rows(); ++i)
    for (Eigen::Index j = i + 1; j < c.correlation.cols(); ++j)
      if (std::abs(c.correlation(i, j)) > 0.8)
        os << "  trade-off: " << c.names[static_cast<size_t>(i)] << " ~ "
           << c.names[static_cast<size_t>(j)] << " (correlation " << fixed(c.correlation(i, j), 2)
           << ")\n";
}

}  // namespace mvtwin::tools
