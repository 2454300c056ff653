// mvtwin import: a real patient from label maps (NIfTI, NRRD, 3D Slicer .seg.nrrd / .seq.nrrd,
// MetaImage), 3D or 3D+t, and landmarks from 3D Slicer markups.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>

#include <nlohmann/json.hpp>

#include "exit_codes.h"
#include "import.h"
#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/image_io.h"
#include "mvtwin/core/markups.h"
#include "mvtwin/core/nifti.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/surface_mesh_io.h"
#include "mvtwin/core/version.h"
#include "mvtwin/detection/patient_import.h"

namespace mvtwin::tools {
namespace fs = std::filesystem;
namespace {

/// "file@time" -> (file, time); no '@' (or a '@' that is part of the path) -> no time.
std::pair<std::string, std::optional<double>> split_time(const std::string& arg) {
  const auto at = arg.rfind('@');
  if (at == std::string::npos || at + 1 == arg.size()) return {arg, std::nullopt};
  const std::string t = arg.substr(at + 1);
  char* end = nullptr;
  const double v = std::strtod(t.c_str(), &end);
  if (end == t.c_str() || *end != '\0') return {arg, std::nullopt};
  if (!std::isfinite(v) || v < 0)
    throw Error(arg + ": the frame time '" + t + "' must be a finite time >= 0 in s");
  return {arg.substr(0, at), v};
}

bool ends_with(std::string s, const std::string& e) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s.size() >= e.size() && s.compare(s.size() - e.size(), e.size(), e) == 0;
}

/// Reads the label maps of one file: a 3D map, a 3D+t sequence (4D NIfTI, Slicer .seq.nrrd,
/// 4D MetaImage), or a Slicer segmentation (.seg.nrrd) whose segment names give the labels.
std::vector<detection::LabelFrame> read_label_file(const std::string& file,
                                                   std::optional<double> time, bool sequence,
                                                   bool explicit_labels) {
  if (!fs::exists(file)) throw Error(file + ": no such file");
  std::vector<detection::LabelFrame> out;
  std::map<std::string, std::string> kv;
  std::vector<ImageVolume> vols;
  if (ends_with(file, ".nrrd") || ends_with(file, ".nhdr")) {
    vols = read_nrrd_series(file, &kv);
  } else {
    vols = read_image_series(file);
  }
  if (detection::is_slicer_segmentation(kv) && !explicit_labels) {
    // Segments found by name; overlapping segments are in layers, read as the 4th axis.
    detection::NamedSegmentation seg = detection::slicer_segmentation(vols, kv, file);
    out.push_back({std::move(seg.label_map), time.value_or(0.0), file, seg.labels, std::nullopt});
    return out;
  }
  if (vols.size() > 1 && !sequence) {
    throw Error(file + ": holds " + std::to_string(vols.size()) +
                " frames; give it with --sequence (3D+t), not --frame");
  }
  for (size_t f = 0; f < vols.size(); ++f) {
    const double t = vols.size() > 1 ? vols[f].time_s : time.value_or(vols[f].time_s);
    out.push_back({std::move(vols[f]), t,
                   vols.size() > 1 ? file + "[" + std::to_string(f) + "]" : file, std::nullopt,
                   std::nullopt});
  }
  return out;
}

std::string fmt(double v, int prec = 2) {
  if (std::isnan(v)) return "n/a";
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", prec, v);
  return b;
}

nlohmann::json stats_json(const DistanceStats& d) {
  return {{"mean_mm", d.mean},
          {"sd_mm", d.sd},
          {"p95_mm", d.p95},
          {"max_mm", d.max},
          {"count", d.count}};
}

}  // namespace

int run_import(const ImportArgs& a) {
  if (a.frames.empty() && a.sequences.empty() && a.meshes.empty())
    throw Error(
        "import: give label maps with --frame FILE[@TIME] or --sequence FILE, or surfaces with "
        "--mesh");
  refuse_overwrite(a.out, a.force);
  if (!a.json_out.empty()) refuse_overwrite(a.json_out, a.force);
  detection::PatientImportOptions o = a.options;
  for (const std::string& r : a.ruptures) {
    const auto colon = r.find(':');
    double s0 = 0, s1 = 0;
    try {
      if (colon == std::string::npos) throw std::invalid_argument(r);
      size_t used0 = 0, used1 = 0;
      s0 = std::stod(r.substr(0, colon), &used0);
      s1 = std::stod(r.substr(colon + 1), &used1);
      if (used0 != colon || used1 != r.size() - colon - 1) throw std::invalid_argument(r);
    } catch (const std::exception&) {
      throw Error("--ruptured-chordae: '" + r + "' is not S0:S1 (e.g. 0.6:0.7)");
    }
    o.ruptured_chordae.push_back({s0, s1});
  }
  const bool explicit_labels = !a.labels.empty();
  if (explicit_labels) {
    o.fit.labels = {(a.labels)[0], (a.labels)[1], a.labels.size() > 2 ? (a.labels)[2] : 0, 0,
                    "explicit"};
  } else {
    o.fit.labels = detection::segmentation_labels(a.convention.empty() ? "mvtool" : a.convention);
  }
  o.fit.labels.papillary = a.papillary;
  o.fit.use_annulus_label = !a.no_ring;
  if (!a.atrium.empty())
    o.fit.atrial_direction = Eigen::Vector3d((a.atrium)[0], (a.atrium)[1], (a.atrium)[2]);
  std::vector<detection::LabelFrame> lf;
  for (const std::string& arg : a.frames) {
    const auto [file, time] = split_time(arg);
    for (auto& f : read_label_file(file, time, false, explicit_labels)) lf.push_back(std::move(f));
    if (!time && a.frames.size() + a.meshes.size() > 1)
      throw Error(file + ": several frames need their times: give each as FILE@TIME (s)");
  }
  for (const std::string& arg : a.meshes) {
    const auto [files, time] = split_time(arg);
    if (!time && a.frames.size() + a.meshes.size() > 1)
      throw Error(files + ": several frames need their times: give each as FILES@TIME (s)");
    std::vector<std::string> names;
    std::stringstream ss(files);
    for (std::string n; std::getline(ss, n, ',');) names.push_back(n);
    if (names.empty() || names.size() > 2)
      throw Error("--mesh " + arg + ": one file (both leaflets) or two (anterior,posterior)");
    std::vector<TriangleMesh> ms;
    for (const std::string& n : names) {
      SurfaceFile sf = read_surface_mesh(n);
      const std::string space = a.mesh_space.empty() ? (sf.space.empty() ? "RAS" : sf.space)
                                                     : (a.mesh_space == "lps" ? "LPS" : "RAS");
      if (sf.space.empty() && a.mesh_space.empty())
        std::cout << n
                  << ": no SPACE= mark in the file: taken as RAS (--mesh-space lps if it is "
                     "LPS, as 3D Slicer writes)\n";
      if (space == "LPS") sf.mesh.V.leftCols(2) *= -1.0;
      ms.push_back(std::move(sf.mesh));
    }
    detection::LabelFrame f;
    f.time_s = time.value_or(0.0);
    f.source = files;
    if (ms.size() == 2) {
      f.meshes = std::make_pair(ms[0], ms[1]);
    } else {
      f.meshes = detection::split_leaflet_meshes(ms[0], names[0]);
      std::cout << names[0]
                << ": two pieces; the rounder one is taken as the anterior leaflet, the "
                   "crescent as the posterior\n";
    }
    lf.push_back(std::move(f));
  }
  for (const std::string& s : a.sequences)
    for (auto& f : read_label_file(s, std::nullopt, true, explicit_labels))
      lf.push_back(std::move(f));
  std::vector<Landmark> ord;
  for (const std::string& n : a.order) {
    const auto l = detection::landmark_from_label(n);
    if (!l) throw Error("--markup-order: '" + n + "' names no landmark (see docs/import.md)");
    ord.push_back(*l);
  }
  std::vector<detection::LandmarkInput> lm;
  for (const std::string& arg : a.markups) {
    const auto [file, time] = split_time(arg);
    const MarkupList m = read_markups(file);
    for (auto& x : detection::landmarks_from_markups(m, file, time, ord)) lm.push_back(x);
  }
  std::cout << "fitting " << lf.size() << " frame(s) (" << o.fit.labels.describe() << ")\n";
  detection::PatientImport r = detection::import_patient(std::move(lf), lm, o);
  r.patient.provenance.command = a.command_line;
  const ValveSequence& seq = r.patient.sequence;
  nlohmann::json report = {{"patient_id", r.patient.id},
                           {"synthetic", false},
                           {"labels", o.fit.labels.describe()},
                           {"end_diastole", seq.end_diastole},
                           {"first_closed", seq.first_closed},
                           {"assumed", r.assumed},
                           {"notes", r.notes},
                           {"frames", nlohmann::json::array()}};
  report.update(provenance(a.command_line));
  std::ostringstream rep;
  for (size_t f = 0; f < r.fits.size(); ++f) {
    const detection::FrameFit& fit = r.fits[f];
    const std::string phase = static_cast<int>(f) == seq.end_diastole   ? "  [end-diastole]"
                              : static_cast<int>(f) == seq.first_closed ? "  [first closed]"
                                                                        : "";
    rep << "frame " << f << " (" << fit.source << ") t=" << fmt(seq.frames[f].time_s, 3) << " s"
        << phase << ": " << fit.anterior_voxels << " anterior / " << fit.posterior_voxels
        << " posterior voxels, orifice " << fmt(fit.orifice_area_mm2, 0) << " mm^2\n";
    rep << "  surface -> mask " << fmt(fit.surface_to_mask.mean) << " mm (p95 "
        << fmt(fit.surface_to_mask.p95) << "), atrial mask -> surface "
        << fmt(fit.mask_to_surface.mean) << " mm (p95 " << fmt(fit.mask_to_surface.p95) << ")\n";
    rep << "  annulus: " << fit.annulus_source;
    if (fit.annulus_to_label) rep << ", to its label " << fmt(fit.annulus_to_label->mean) << " mm";
    if (fit.rim_vs_label)
      rep << "; the leaflet rim is " << fmt(fit.rim_vs_label->mean) << " mm from it ("
          << fmt(fit.rim_to_label_voxels->mean) << " mm from the label's voxels)";
    rep << "\n";
    std::string obs, ass;
    for (int l = 0; l < kNumLandmarks; ++l) {
      if (!seq.frames[f].landmark_observed[l]) continue;
      (seq.frames[f].landmark_assumed[l] ? ass : obs) += " " + std::string(kLandmarkNames[l]);
    }
    rep << "  observed:" << (obs.empty() ? " -" : obs) << "\n";
    if (!ass.empty()) rep << "  ASSUMED: " << ass << "\n";
    for (const auto& w : fit.warnings) rep << "  warning: " << w << "\n";
    nlohmann::json fj = {{"source", fit.source},
                         {"time_s", seq.frames[f].time_s},
                         {"orifice_area_mm2", fit.orifice_area_mm2},
                         {"annulus_source", fit.annulus_source},
                         {"surface_to_mask", stats_json(fit.surface_to_mask)},
                         {"mask_to_surface", stats_json(fit.mask_to_surface)},
                         {"anterior_voxels", fit.anterior_voxels},
                         {"posterior_voxels", fit.posterior_voxels},
                         {"annulus_voxels", fit.annulus_voxels},
                         {"notes", fit.notes},
                         {"warnings", fit.warnings}};
    if (fit.annulus_to_label) fj["annulus_to_label"] = stats_json(*fit.annulus_to_label);
    if (fit.rim_vs_label) fj["rim_vs_label"] = stats_json(*fit.rim_vs_label);
    if (fit.rim_to_label_voxels) fj["rim_to_label_voxels"] = stats_json(*fit.rim_to_label_voxels);
    report["frames"].push_back(fj);
  }
  for (const auto& n : r.notes) rep << "note: " << n << "\n";
  for (const auto& name : r.assumed) rep << "ASSUMED: " << name << "\n";
  std::cout << rep.str();
  r.patient.import_report = rep.str();
  write_patient(a.out, r.patient);
  if (!a.json_out.empty()) {
    const std::string text = report.dump(2);
    write_atomically(a.json_out, [&](const fs::path& tmp) {
      std::ofstream f(tmp);
      f << text << "\n";
      f.close();
      if (!f) throw Error(a.json_out + ": write failed");
    });
  }
  std::cout << "wrote " << a.out << " (real patient " << r.patient.id << ", " << seq.num_frames()
            << " frame(s))\n";
  return kExitOk;
}

void register_import(CLI::App& app, Context& ctx) {
  auto* cmd = app.add_subcommand(
      "import", "Build a real patient from segmentations (label maps) and landmarks");
  cmd->footer(
      "Examples:\n"
      "  mvtwin import --frame seg/frame_11.nii.gz@0.40 --frame seg/frame_15.nii.gz@0.55 "
      "--markups seg/tips_11.mrk.json@0.40 --out imported.h5\n"
      "  mvtwin import --sequence seg_seq/labels.seq.nrrd --convention mvseg --out "
      "imported_seq.h5\n"
      "  mvtwin import --frame seg/frame_15.nii.gz --out one_closed.h5   # measured, not "
      "simulated\n"
      "(the label maps of mvtwin export observed.h5 --labelmap seg/ ...; from 3D Slicer: e.g.\n"
      "--frame ed.seg.nrrd@0.00 --frame es.seg.nrrd@0.24 --markups tips.mrk.json; surface\n"
      "meshes: --mesh ed_al.stl,ed_pl.stl@0 --mesh es.vtp@0.24)\n"
      "Label maps: .nii/.nii.gz (3D, or 4D with --sequence), .nrrd/.nhdr, 3D Slicer .seg.nrrd "
      "(segments found by\n"
      "name) and .seq.nrrd, .mha/.mhd. Labels: --convention mvtool (1 annulus, 2 anterior, 3 "
      "posterior; the\n"
      "default) or mvseg (1 posterior, 2 anterior, no annulus), or --labels "
      "ANTERIOR,POSTERIOR[,ANNULUS] (0: none).\n"
      "Without an annulus label the annulus is the leaflets' attachment rim. Landmarks: --markups "
      "FILE[@TIME]\n"
      "(.mrk.json or .fcsv; matched by label, see docs/import.md; without @TIME: every frame). "
      "Papillary tips\n"
      "neither labelled nor given are ASSUMED from published anatomy, and every report says so.\n"
      "End-diastole and the first closed frame: the largest and smallest leaflet opening, or\n"
      "--end-diastole I --first-closed I (frame indices in time order).");
  auto a = std::make_shared<ImportArgs>();
  cmd->add_option("--frame", a->frames,
                  "label map of one frame, FILE or FILE@TIME (s); repeatable");
  cmd->add_option("--sequence", a->sequences,
                  "3D+t label maps (4D NIfTI, .seq.nrrd, 4D .mha); times from the file");
  cmd->add_option("--mesh", a->meshes,
                  "leaflet surfaces of one frame instead of a label map: ANTERIOR,POSTERIOR[@TIME] "
                  "or BOTH[@TIME] "
                  "(.stl, .ply, .vtk, .vtp); repeatable");
  cmd->add_option("--mesh-space", a->mesh_space,
                  "ras or lps (default: the file's SPACE= mark, else RAS)")
      ->check(CLI::IsMember({"ras", "lps"}));
  cmd->add_option("--markups", a->markups,
                  "3D Slicer markups FILE or FILE@TIME (.mrk.json, .fcsv); repeatable");
  cmd->add_option("--markup-order", a->order,
                  "landmark names of unlabelled markup points, in order")
      ->delimiter(',');
  auto* conv =
      cmd->add_option("--convention", a->convention, "label convention: mvtool (default) or mvseg");
  cmd->add_option("--labels", a->labels,
                  "label values ANTERIOR,POSTERIOR[,ANNULUS] (0: no annulus label)")
      ->delimiter(',')
      ->expected(2, 3)
      ->excludes(conv);
  cmd->add_option("--papillary-label", a->papillary,
                  "label value of the papillary muscles (their tips)");
  cmd->add_flag("--no-annulus-label", a->no_ring,
                "fit the annulus to the leaflet rim even when it is labelled");
  cmd->add_option("--atrium", a->atrium,
                  "direction into the left atrium, x,y,z (default: inferred)")
      ->delimiter(',')
      ->expected(3);
  cmd->add_option("--end-diastole", a->options.end_diastole,
                  "end-diastolic frame index (time order; default: from the opening)");
  cmd->add_option("--first-closed", a->options.first_closed,
                  "first closed frame index (default: from the opening)");
  cmd->add_option("--ures", a->options.fit.ures, "grid points around the annulus (even, >= 8)")
      ->default_val(30);
  cmd->add_option("--vres", a->options.fit.vres, "grid points from annulus to free edge (>= 3)")
      ->default_val(30);
  cmd->add_option("--id", a->options.id, "patient identifier (default: the first file's name)");
  cmd->add_option("--ruptured-chordae", a->ruptures,
                  "torn marginal chordae seen in the images, S0:S1 (grid coordinate s around the "
                  "annulus from the anterolateral commissure, anterior leaflet below 0.5); "
                  "repeatable");
  cmd->add_option("--json", a->json_out, "also write the fit report as JSON");
  cmd->add_option("--out", a->out, "patient file to write (HDF5)")->required();
  cmd->add_flag("--force", a->force, "replace an existing file");
  run_on_parse(cmd, ctx, a, run_import);
}

}  // namespace mvtwin::tools
