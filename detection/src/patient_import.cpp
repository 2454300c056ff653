#include "mvtwin/detection/patient_import.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <limits>
#include <numbers>

#include <Eigen/Dense>

#include "mvtwin/core/annulus_plane.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/version.h"

namespace mvtwin::detection {
namespace {

std::string squash(std::string_view s) {
  std::string out;
  for (char c : s)
    if (std::isalnum(static_cast<unsigned char>(c)))
      out += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string fmt(double v, int prec = 2) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", prec, v);
  return b;
}

// Published anatomy for what is not given (Mansi et al. 2012 Sec. 2.2 and the echo literature
// summarized in docs/virtual-patients.md): papillary tips 26.5 mm below the annulus plane,
// 30 mm apart, 4 mm posterior of the annulus centre.
constexpr double kPapillaryDepthMm = 26.5;
constexpr double kPapillarySeparationMm = 30.0;
constexpr double kPapillaryPosteriorMm = 4.0;

}  // namespace

std::optional<Landmark> landmark_from_label(std::string_view label) {
  const std::string s = squash(label);
  if (s.empty()) return std::nullopt;
  auto has = [&](const char* w) { return s.find(w) != std::string::npos; };
  const bool al = has("anterolateral") || has("anteriorlateral") || s.rfind("al", 0) == 0 ||
                  has("left") || s == "alpm" || s == "apm";
  const bool pm = has("posteromedial") || has("posteriormedial") ||
                  (s.rfind("pm", 0) == 0 && s != "pml") || has("right") || s == "pmpm" ||
                  s == "ppm";
  if (s == "alpm" || s == "apm" || (has("papillary") && al))
    return Landmark::kAnterolateralPapillaryTip;
  if (s == "pmpm" || s == "ppm" || (has("papillary") && pm))
    return Landmark::kPosteromedialPapillaryTip;
  if (has("trigone") && al) return Landmark::kAnterolateralTrigone;
  if (has("trigone") && pm) return Landmark::kPosteromedialTrigone;
  if (has("commissure") && al) return Landmark::kAnterolateralCommissure;
  if (has("commissure") && pm) return Landmark::kPosteromedialCommissure;
  if ((has("posterior") && (has("annulus") || has("midpoint"))) || s == "pannulus")
    return Landmark::kPosteriorAnnulusMidpoint;
  if (has("anterior") && has("tip")) return Landmark::kAnteriorLeafletTip;
  if (has("posterior") && has("tip")) return Landmark::kPosteriorLeafletTip;
  for (int l = 0; l < kNumLandmarks; ++l)
    if (s == squash(kLandmarkNames[l])) return static_cast<Landmark>(l);
  return std::nullopt;
}

std::vector<LandmarkInput> landmarks_from_markups(const MarkupList& m, const std::string& source,
                                                  std::optional<double> time_s,
                                                  const std::vector<Landmark>& order) {
  std::vector<LandmarkInput> out;
  std::vector<std::optional<Landmark>> by_label;
  bool all = true;
  for (const auto& p : m.points) {
    by_label.push_back(landmark_from_label(p.label));
    all = all && by_label.back().has_value();
  }
  if (!order.empty()) {
    if (order.size() != m.points.size())
      throw Error(source + ": " + std::to_string(m.points.size()) + " points but " +
                  std::to_string(order.size()) + " names in the given order");
    for (size_t i = 0; i < order.size(); ++i)
      out.push_back({order[i], m.points[i].position, time_s, source});
  } else if (all) {
    for (size_t i = 0; i < by_label.size(); ++i)
      out.push_back({*by_label[i], m.points[i].position, time_s, source});
  } else if (m.points.size() == 2) {
    out.push_back({Landmark::kAnterolateralPapillaryTip, m.points[0].position, time_s, source});
    out.push_back({Landmark::kPosteromedialPapillaryTip, m.points[1].position, time_s, source});
  } else {
    std::string bad;
    for (size_t i = 0; i < by_label.size(); ++i)
      if (!by_label[i]) bad += (bad.empty() ? "'" : ", '") + m.points[i].label + "'";
    throw Error(source + ": the markup labels " + bad +
                " name no landmark (use the names in docs/import.md, or give the order with "
                "--markup-order)");
  }
  for (size_t i = 0; i < out.size(); ++i)
    for (size_t j = i + 1; j < out.size(); ++j)
      if (out[i].landmark == out[j].landmark)
        throw Error(source + ": two points are the " + std::string(name(out[i].landmark)));
  return out;
}

bool PatientImportOptions::is_valid(std::string* error) const {
  if (!fit.is_valid(error)) return false;
  if (end_diastole < -1 || first_closed < -1) {
    *error = "frame indices must be >= 0 (or -1: found from the opening)";
    return false;
  }
  if (end_diastole >= 0 && first_closed >= 0 && first_closed <= end_diastole) {
    *error = "the first closed frame must come after end-diastole";
    return false;
  }
  for (const ChordaeRupture& r : ruptured_chordae) {
    if (!r.is_valid()) {
      *error = "a chordae rupture must have 0 <= s_begin < s_end <= 1";
      return false;
    }
  }
  if (!(max_commissure_jump_mm > 0)) {
    *error = "max_commissure_jump_mm must be positive";
    return false;
  }
  return true;
}

PatientImport import_patient(std::vector<LabelFrame> frames,
                             const std::vector<LandmarkInput>& landmarks,
                             const PatientImportOptions& opt) {
  std::string err;
  if (!opt.is_valid(&err)) throw Error("import: " + err);
  if (frames.empty()) throw Error("import: no frames given");
  std::stable_sort(frames.begin(), frames.end(),
                   [](const LabelFrame& a, const LabelFrame& b) { return a.time_s < b.time_s; });
  for (size_t i = 0; i < frames.size(); ++i) {
    if (!std::isfinite(frames[i].time_s))
      throw Error(frames[i].source + ": the frame time is not a number");
    if (i > 0 && frames[i].time_s - frames[i - 1].time_s < 1e-6)
      throw Error("import: " + frames[i - 1].source + " and " + frames[i].source +
                  " have the same time (" + fmt(frames[i].time_s, 3) +
                  " s); give each frame its own time (FILE@TIME)");
  }
  const int F = static_cast<int>(frames.size());
  PatientImport out;
  for (const LabelFrame& lf : frames) {
    SegmentationFitOptions fo = opt.fit;
    if (lf.labels_override) fo.labels = *lf.labels_override;
    FrameFit fit = lf.meshes ? fit_surface_frame(lf.meshes->first, lf.meshes->second, lf.source, fo)
                             : fit_segmentation_frame(lf.labels, lf.source, fo);
    fit.frame.time_s = lf.time_s;
    out.fits.push_back(std::move(fit));
  }
  // Frames whose grids disagree: the atrial side flips, or the commissures jump.
  const Eigen::Vector3d n0 = atrial_direction(out.fits[0].frame.annulus);
  for (int f = 1; f < F; ++f) {
    const ValveFrame& a = out.fits[f - 1].frame;
    const ValveFrame& b = out.fits[f].frame;
    const double jump = (a.annulus.row(0) - b.annulus.row(0)).norm();
    const double cos_n = atrial_direction(b.annulus).dot(n0);
    if (cos_n < 0.7 || jump > opt.max_commissure_jump_mm) {
      throw Error("import: the grids of " + frames[f - 1].source + " and " + frames[f].source +
                  " disagree (anterolateral commissure moves " + fmt(jump, 1) +
                  " mm, atrial directions " +
                  fmt(std::acos(std::clamp(cos_n, -1.0, 1.0)) * 180 / std::numbers::pi, 0) +
                  " degrees apart): are they the same patient, in the same image space, with the "
                  "same labels?");
    }
  }
  // End-diastole and the first closed frame.
  int ed = opt.end_diastole, fc = opt.first_closed;
  if ((ed >= F) || (fc >= F))
    throw Error("import: frame index out of range (" + std::to_string(F) +
                " frames, counted from 0 in time order)");
  std::string orifices;
  for (int f = 0; f < F; ++f) orifices += (f ? ", " : "") + fmt(out.fits[f].orifice_area_mm2, 0);
  if (F == 1) {
    if (ed == 0) {
      fc = -1;
    } else {
      fc = 0;
      ed = -1;
    }
    out.notes.push_back(
        "one frame: it can be measured, but simulate, calibrate and clip need an end-diastolic and "
        "a first closed frame");
  } else {
    if (fc < 0) {
      int lo = ed >= 0 ? ed + 1 : 1;
      fc = lo;
      for (int f = lo; f < F; ++f)
        if (out.fits[f].orifice_area_mm2 < out.fits[fc].orifice_area_mm2) fc = f;
    }
    if (ed < 0) {
      ed = 0;
      for (int f = 0; f < fc; ++f)
        if (out.fits[f].orifice_area_mm2 > out.fits[ed].orifice_area_mm2) ed = f;
    }
    if (fc <= ed) throw Error("import: the first closed frame must come after end-diastole");
    out.notes.push_back(
        "end-diastole: frame " + std::to_string(ed) + " (" + fmt(frames[ed].time_s, 3) + " s)" +
        (opt.end_diastole >= 0 ? " as given" : ", the largest orifice before the closed frame") +
        "; first closed: frame " + std::to_string(fc) + " (" + fmt(frames[fc].time_s, 3) + " s)" +
        (opt.first_closed >= 0 ? " as given" : ", the smallest orifice") +
        "; orifice areas mm^2: " + orifices);
    if (out.fits[fc].orifice_area_mm2 > 0.5 * out.fits[ed].orifice_area_mm2) {
      out.notes.push_back(
          "warning: the first closed frame's orifice (" + fmt(out.fits[fc].orifice_area_mm2, 0) +
          " mm^2) is more than half the end-diastolic one: is the valve closed in any frame?");
    }
  }

  Patient& p = out.patient;
  p.synthetic = false;
  p.id = opt.id.empty() ? std::filesystem::path(frames[0].source).filename().string() : opt.id;
  p.provenance.version = kVersion;
  p.provenance.created_utc = utc_now_iso8601();
  std::string src = "segmentation import (" + opt.fit.labels.describe() + "):";
  for (const LabelFrame& lf : frames) src += " " + lf.source + "@" + fmt(lf.time_s, 3);
  p.provenance.source = src;
  ValveSequence& seq = p.sequence;
  seq.ures = opt.fit.ures;
  seq.vres = opt.fit.vres;
  seq.end_diastole = ed;
  seq.first_closed = fc;
  seq.ruptured_chordae = opt.ruptured_chordae;
  for (const FrameFit& fit : out.fits) seq.frames.push_back(fit.frame);

  // Landmarks from markups: a time picks the frame; no time means every frame.
  for (const LandmarkInput& in : landmarks) {
    if (!in.position.allFinite())
      throw Error(in.source + ": " + std::string(name(in.landmark)) + " has a NaN/Inf coordinate");
    std::vector<int> targets;
    if (in.time_s) {
      for (int f = 0; f < F; ++f)
        if (std::abs(seq.frames[f].time_s - *in.time_s) < 5e-4) targets.push_back(f);
      if (targets.empty())
        throw Error(in.source + ": no frame at " + fmt(*in.time_s, 3) + " s for " +
                    std::string(name(in.landmark)));
    } else {
      for (int f = 0; f < F; ++f) targets.push_back(f);
    }
    for (int f : targets) {
      // A landmark placed in another space (or another patient) lies far from the valve.
      const Eigen::Vector3d c = seq.frames[f].annulus.colwise().mean().transpose();
      const double dist = (in.position - c).norm();
      if (dist > 80.0) {
        throw Error(in.source + ": " + std::string(name(in.landmark)) + " lies " + fmt(dist, 0) +
                    " mm from the valve's centre: are the markups in another coordinate space "
                    "(image IJK, or LPS "
                    "without saying so)?");
      }
      seq.frames[f].landmarks[index(in.landmark)] = in.position;
      seq.frames[f].landmark_observed[index(in.landmark)] = true;
      seq.frames[f].landmark_assumed[index(in.landmark)] = false;
    }
    out.notes.push_back(std::string(name(in.landmark)) + ": from " + in.source +
                        (in.time_s ? " at " + fmt(*in.time_s, 3) + " s" : " (every frame)"));
  }

  // Papillary tips: observed in some frames -> the others hold the nearest observed frame's;
  // observed nowhere -> estimated from anatomy relative to each frame's annulus (assumed).
  for (Landmark l : {Landmark::kAnterolateralPapillaryTip, Landmark::kPosteromedialPapillaryTip}) {
    std::vector<int> have;
    for (int f = 0; f < F; ++f)
      if (seq.frames[f].observed(l)) have.push_back(f);
    if (!have.empty()) {
      for (int f = 0; f < F; ++f) {
        if (seq.frames[f].observed(l)) continue;
        int best = have[0];
        for (int h : have)
          if (std::abs(h - f) < std::abs(best - f)) best = h;
        seq.frames[f].landmarks[index(l)] = seq.frames[best].landmark(l);
        seq.frames[f].landmark_observed[index(l)] = true;
        seq.frames[f].landmark_assumed[index(l)] = true;
        out.assumed.push_back(std::string(name(l)) + " in frame " + std::to_string(f) +
                              ": held at frame " + std::to_string(best) +
                              "'s position (no papillary motion known there)");
      }
      continue;
    }
    for (int f = 0; f < F; ++f) {
      ValveFrame& fr = seq.frames[f];
      const Eigen::Vector3d c = fr.annulus.colwise().mean().transpose();
      const Eigen::Vector3d z = atrial_direction(fr.annulus);
      Eigen::Vector3d y = (fr.annulus.row(0) - fr.annulus.row(seq.ures / 2)).transpose();
      y = (y - y.dot(z) * z).normalized();  // towards the anterolateral commissure
      Eigen::Vector3d x = y.cross(z);
      const Eigen::Vector3d ant = fr.annulus.row(seq.ures / 4).transpose() - c;
      if (x.dot(ant) < 0) x = -x;  // towards the anterior annulus
      const double side = l == Landmark::kAnterolateralPapillaryTip ? 1.0 : -1.0;
      fr.landmarks[index(l)] = c - kPapillaryPosteriorMm * x +
                               side * 0.5 * kPapillarySeparationMm * y - kPapillaryDepthMm * z;
      fr.landmark_observed[index(l)] = true;
      fr.landmark_assumed[index(l)] = true;
    }
    out.assumed.push_back(std::string(name(l)) + ": ASSUMED in every frame, " +
                          fmt(kPapillaryDepthMm, 1) + " mm below the annulus plane, " +
                          fmt(kPapillarySeparationMm / 2, 0) +
                          " mm to its side of the annulus centre along the commissures, " +
                          fmt(kPapillaryPosteriorMm, 0) +
                          " mm posterior (published anatomy; no papillary label or markup given)");
  }
  if (!out.assumed.empty()) p.provenance.source += "; ASSUMED: " + seq.assumed_landmarks();
  seq.validate(p.id.c_str());
  return out;
}

}  // namespace mvtwin::detection
