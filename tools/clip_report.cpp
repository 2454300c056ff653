#include "clip_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "mvtwin/core/error.h"
#include "mvtwin/studies/en_face.h"
#include "mvtwin/studies/plot.h"
#include "mvtwin/studies/report.h"

namespace mvtwin::tools {
namespace fs = std::filesystem;

namespace {

std::string num(double v, int digits) {
  if (!std::isfinite(v)) return "n/a";
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

/// "5.0 (4.3-5.6)": the value with its 95 % interval where there is one.
std::string with_interval(const inverse::ClipScenario& s, const inverse::ClosureQuality& before,
                          int k, int digits) {
  const Eigen::VectorXd v = inverse::clip_outcomes(s, before);
  std::string out = num(v[k], digits);
  const inverse::ClipUncertainty& u = s.uncertainty;
  if (u.computed && std::isfinite(v[k])) {
    if (std::isfinite(u.sd[k])) {
      const double h = inverse::kZ95 * u.sd[k];
      out += " (" + num(std::max(0.0, v[k] - h), digits) + "-" + num(v[k] + h, digits) + ")";
    } else {
      out += " (?)";
    }
  }
  return out;
}

std::vector<std::pair<double, double>> leaks(const RegurgitantOrifice& o) {
  std::vector<std::pair<double, double>> out;
  for (const Opening& op : o.openings) out.emplace_back(op.begin, op.end);
  return out;
}

std::vector<double> positions(const std::vector<inverse::ClipSite>& sites) {
  std::vector<double> p;
  for (const auto& s : sites) p.push_back(s.position);
  return p;
}

/// The closed and the open pictures of one scenario; returns the files written (may be none).
std::vector<std::string> pictures(const fs::path& dir, const std::string& stem,
                                  const std::string& label, const inverse::ClipScenario& s) {
  std::vector<std::string> files;
  if (s.quality.converged && s.quality.closed_surface) {
    studies::EnFaceView v;
    v.title = label + ": closed (end of systole)";
    v.lines = {"EROA " + num(s.quality.orifice.eroa_mm2, 1) + " mm^2 (" +
               std::string(mr_grade_name(s.quality.orifice.grade)) + " MR), " +
               std::to_string(s.quality.orifice.openings.size()) +
               " opening(s), marked red along the line"};
    v.clips = positions(s.sites);
    v.openings = leaks(s.quality.orifice);
    studies::write_en_face_png(dir / (stem + "_systole.png"), *s.quality.closed_surface, v);
    files.push_back(stem + "_systole.png");
  }
  if (s.opening.converged && s.opening.open_surface) {
    studies::EnFaceView v;
    v.title = label + ": open (diastole, 5 mmHg)";
    v.lines = {"MVA " + num(s.opening.mva_cm2, 2) + " cm^2 in " +
               std::to_string(s.opening.openings_cm2.size()) + " orifice(s), mean gradient " +
               num(s.opening.gradient_mmhg, 1) + " mmHg" +
               (s.opening.stenosis ? " - STENOSIS" : "")};
    v.clips = positions(s.sites);
    studies::write_en_face_png(dir / (stem + "_diastole.png"), *s.opening.open_surface, v);
    files.push_back(stem + "_diastole.png");
  }
  return files;
}

}  // namespace

void write_clip_report(const fs::path& dir, const ClipPlan& plan) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw Error(dir.string() + ": cannot create the report folder (" + ec.message() + ")");
  const Patient& p = *plan.patient;
  const inverse::ClipScenario& before = plan.before;
  studies::Report r("Clip plan for " + p.id + (p.synthetic ? " [SYNTHETIC]" : ""));
  r.paragraph(
      "Where, and with which device, an edge-to-edge clip is predicted to stop the leak without "
      "narrowing the valve. Parameters: " +
      plan.parameters_from + ". " +
      (plan.ranked.empty() || !plan.ranked.front().uncertainty.computed
           ? "No intervals (" + plan.intervals_why_not + ")."
           : "Numbers in brackets are 95 % intervals propagated from the calibration's "
             "covariance (docs/clip-devices.md, \"How sure the answer is\"); they cover the fit's "
             "noise, not the model's own error."));

  r.heading("Without a clip");
  const RegurgitantOrifice& o = before.quality.orifice;
  if (before.quality.converged) {
    std::string t = "EROA **" + with_interval(before, before.quality, 0, 1) + " mm^2**: **" +
                    std::string(mr_grade_name(o.grade)) + " MR** (ASE 2017); AROA " +
                    num(o.aroa_mm2, 1) + " mm^2 in " + std::to_string(o.openings.size()) +
                    " opening(s); coaptation " + num(o.coaptation_length_mm, 1) + " mm long, " +
                    num(o.coaptation_depth_mm, 1) + " mm below the annulus.";
    if (before.opening.converged)
      t += " Open: MVA " + num(before.opening.mva_cm2, 2) + " cm^2, mean gradient " +
           num(before.opening.gradient_mmhg, 1) + " mmHg.";
    r.paragraph(t);
    const inverse::EverestCriteria& e = plan.everest;
    auto ok = [](bool b) { return b ? std::string("met") : std::string("**NOT MET**"); };
    r.table({"EVEREST anatomic criterion", "measured", ""},
            {{"coaptation length >= 2 mm", num(e.coaptation_length_mm, 1) + " mm",
              ok(e.coaptation_length_ok)},
             {"coaptation depth < 11 mm", num(e.coaptation_depth_mm, 1) + " mm",
              ok(e.coaptation_depth_ok)},
             {"flail gap < 10 mm (widest gap)", num(e.flail_gap_mm, 1) + " mm", ok(e.flail_gap_ok)},
             {"flail width < 15 mm (largest opening's length)", num(e.flail_width_mm, 1) + " mm",
              ok(e.flail_width_ok)}});
  } else {
    r.paragraph("The valve without a clip failed to simulate: " + before.quality.reason);
  }
  for (const std::string& f : pictures(dir, "no_clip", "Without a clip", before))
    r.figure(f, std::string("Without a clip, ") +
                    (f.find("systole") != std::string::npos ? "closed" : "open") +
                    ", seen from the atrium (anterior leaflet blue, at the top; leaks red).");

  r.heading("Options, ranked by the EROA left");
  std::vector<std::vector<std::string>> rows;
  studies::PlotSeries eroa{"EROA after the clip", {}, {}, false, true, {}};
  bool any_sd = false;
  for (size_t i = 0; i < plan.ranked.size(); ++i) {
    const inverse::ClipScenario& s = plan.ranked[i];
    const inverse::ClipFlags f = inverse::clip_flags(s.quality.clip_grasps);
    const bool tied = i > 0 && inverse::indistinguishable(plan.sigma, plan.ranked.front(), s);
    if (!s.quality.converged) {
      rows.push_back({std::to_string(i + 1), inverse::describe_sites(s.sites),
                      "failed: " + s.quality.reason, "", "", "", "", "", "", ""});
      continue;
    }
    const inverse::GraspLoads g = inverse::grasp_loads(before.quality, s.quality);
    rows.push_back(
        {std::to_string(i + 1), inverse::describe_sites(s.sites) + (tied ? " (= 1)" : ""),
         with_interval(s, before.quality, 0, 1),
         std::string(mr_grade_name(s.quality.orifice.grade)),
         s.opening.computed ? with_interval(s, before.quality, 1, 2) : "not opened",
         s.opening.converged ? with_interval(s, before.quality, 2, 1) : "",
         s.opening.converged ? (s.opening.stenosis ? "**yes**" : "no") : "",
         num(f.min_insertion_mm, 1) + (f.detachment_risk ? " **risk**" : ""),
         num(g.stress_p95_before_kpa, 0) + " -> " + with_interval(s, before.quality, 3, 0),
         s.opening.fallback.empty() ? "" : "opened from end-diastole"});
    if (i < 15) {
      eroa.x.push_back(static_cast<double>(i + 1));
      eroa.y.push_back(s.quality.orifice.eroa_mm2);
      const double sd = s.uncertainty.computed ? s.uncertainty.sd[0] : 0.0;
      eroa.y_error.push_back(std::isfinite(sd) ? inverse::kZ95 * sd : 0.0);
      any_sd = any_sd || s.uncertainty.computed;
    }
  }
  r.table({"rank", "option", "EROA mm^2", "MR", "MVA cm^2", "gradient mmHg", "stenosis",
           "shallowest insertion mm", "stress p95 kPa (no clip -> clip)", "note"},
          rows);
  r.paragraph(
      "\"(= 1)\": cannot be told from option 1 (their EROAs differ by less than 1.96 SD of the "
      "difference). MVA and gradient are computed for the best options only (--open-best). "
      "Stenosis: MVA < 1.5 cm^2 or mean gradient >= 5 mmHg. Detachment risk: a leaflet inserting "
      "less than 4 mm into the device (an mvtwin assumption).");
  if (!eroa.x.empty()) {
    studies::Plot pl;
    pl.title = "EROA left by each option" + std::string(any_sd ? " (95 % intervals)" : "");
    pl.x_label = "rank";
    pl.y_label = "EROA (mm^2)";
    if (!any_sd) eroa.y_error.clear();
    pl.series.push_back(eroa);
    if (before.quality.converged) pl.h_lines.push_back({o.eroa_mm2, "without a clip"});
    pl.h_lines.push_back({20.0, "moderate MR (ASE 2017)"});
    pl.write_png(dir / "eroa.png");
    r.figure("eroa.png", "The options' EROA, best first, against the grades' thresholds.");
  }

  r.heading("The best options, closed and open");
  for (size_t i = 0; i < std::min<size_t>(3, plan.ranked.size()); ++i) {
    const inverse::ClipScenario& s = plan.ranked[i];
    const std::string label = std::to_string(i + 1) + ". " + inverse::describe_sites(s.sites);
    for (const std::string& f : pictures(dir, "option_" + std::to_string(i + 1), label, s))
      r.figure(f, label + (f.find("systole") != std::string::npos ? ", closed" : ", open") +
                      ", seen from the atrium (the device black, leaks red).");
  }

  r.heading("Assumptions");
  r.paragraph(
      "The device grasps a band of each leaflet as wide as its arms and as deep as the leaflet "
      "inserts (from the geometry of the closing valve, capped by the arm), on the open valve "
      "with the pressure off, then closes under the patient's motion and pressure; the grasped "
      "bands are held face to face by stiff ties. EROA = 0.611 x AROA (Kirchhoff's slit); MR "
      "grade by ASE 2017 (mild < 20, moderate 20-39, severe >= 40 mm^2). Diastole: 5 mmHg "
      "transmitral pressure on the widest open frame, annulus and papillary tips held there; "
      "MVA seen along the annulus normal; mean gradient from Gorlin's relation (constant 37.7) "
      "at 70 mL over 0.5 s. The leaflets' law is linear with the paper's moduli: opened clipped "
      "valves are likely too narrow (docs/clip-devices.md). PASCAL dimensions are unverified.");
  r.how_made(plan.command_line, std::to_string(plan.jobs) + " simulations at once", plan.wall_s);
  r.write(dir);
}

}  // namespace mvtwin::tools
