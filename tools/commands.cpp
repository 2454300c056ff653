#include "commands.h"
#include "exit_codes.h"
#include "output_files.h"
#include "progress.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "mvtwin/core/annulus_measures.h"
#include "mvtwin/core/annulus_plane.h"
#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/image_io.h"
#include "mvtwin/core/markups.h"
#include "mvtwin/core/nifti.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/patient_vtk.h"
#include "mvtwin/core/point_to_mesh_distance.h"
#include "mvtwin/core/simulation_file.h"
#include "mvtwin/core/units.h"
#include "mvtwin/core/version.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/detection/label_map.h"
#include "mvtwin/forward/closure_scene.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/forward/closure_simulation.h"
#include "mvtwin/forward/model_vtk.h"
#include "mvtwin/forward/valve_model.h"
#include "mvtwin/forward/virtual_closure.h"

namespace mvtwin::tools {
namespace fs = std::filesystem;
namespace {

std::string name_of_landmark(Landmark l) {
  std::string s(name(l));
  for (char& c : s)
    if (c == '_') c = ' ';
  return s;
}

void refuse_overwrite(const fs::path& p, bool force) {
  if (fs::exists(p) && !force) {
    throw Error(p.string() + ": already exists (use --force to replace it)");
  }
}

/// The landmarks estimated from anatomy rather than observed: every report that uses them
/// says so, because the papillary tips drive the closure.
void print_assumed(const Patient& p, std::ostream& os) {
  const std::string a = p.sequence.assumed_landmarks();
  if (!a.empty())
    os << "ASSUMED   " << a
       << ": estimated from published anatomy, not observed (they drive the closure)\n";
}

std::string fmt(double v, int prec = 2) {
  if (std::isnan(v)) return "n/a";
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", prec, v);
  return b;
}

void print_simulation_info(const SimulationRecord& r, std::ostream& os) {
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
    os << "  t = " << fmt(r.time_s[i], 2) << " s (observed " << fmt(r.observed_time_s[i], 3)
       << " s): tips " << fmt(r.anterior_tip_mm[i]) << " / " << fmt(r.posterior_tip_mm[i])
       << " mm, orifice " << fmt(r.orifice_area_mm2[i], 1) << " of "
       << fmt(r.annulus_area_mm2[i], 0) << " mm^2\n";
  }
  double smax = 0, vmax = 0;
  for (Eigen::Index e = 0; e < r.element_strain.size(); ++e) {
    smax = std::max(smax, r.element_strain[e]);
    vmax = std::max(vmax, r.element_stress_mpa[e]);
  }
  os << "end state " << r.mesh.T.rows() << " tetrahedra; largest principal strain " << fmt(smax, 3)
     << ", largest von Mises stress " << fmt(vmax * 1000.0, 1) << " kPa\n";
}

void print_info(const Patient& p, std::ostream& os) {
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
  os << "sequence  " << s.num_frames() << " frames, t = " << fmt(s.frames.front().time_s, 3)
     << " .. " << fmt(s.frames.back().time_s, 3) << " s; grid ures=" << s.ures << " vres=" << s.vres
     << "; leaflets observed in " << observed << " frames\n";
  os << "phases    end-diastole = "
     << (s.end_diastole >= 0 ? "frame " + std::to_string(s.end_diastole) : "unknown")
     << ", first closed = "
     << (s.first_closed >= 0 ? "frame " + std::to_string(s.first_closed) : "unknown");
  if (s.end_diastole >= 0 && s.first_closed >= 0) {
    os << " (closure " << fmt(s.frames[s.first_closed].time_s - s.frames[s.end_diastole].time_s, 3)
       << " s)";
  }
  os << "\n";
  auto frame_report = [&](int f, const char* label) {
    if (f < 0) return;
    const ValveFrame& fr = s.frames[f];
    const AnnulusMeasures m = annulus_measures(fr);
    os << label << " (frame " << f << ")\n";
    os << "  annulus   AP " << fmt(m.ap_diameter_mm, 1) << " mm, AL-PM "
       << fmt(m.alpm_diameter_mm, 1) << " mm, commissural width " << fmt(m.commissural_width_mm, 1)
       << " mm, intertrigonal " << fmt(m.intertrigonal_mm, 1) << " mm\n";
    os << "            perimeter " << fmt(m.perimeter_mm, 1) << " mm, 3D area "
       << fmt(units::mm2_to_cm2(m.area_3d_mm2)) << " cm^2, height " << fmt(m.height_mm, 1)
       << " mm (" << fmt(100 * m.height_mm / m.commissural_width_mm, 1)
       << " % of commissural width), arcs ant/post " << fmt(m.anterior_arc_mm, 1) << "/"
       << fmt(m.posterior_arc_mm, 1) << " mm\n";
    if (fr.la_surface) {
      const double area = fr.la_surface->triangulate().area();
      os << "  leaflets  AL length " << fmt(fr.la_surface->radial_length_at(0.25), 1)
         << " mm, PL length " << fmt(fr.la_surface->radial_length_at(0.75), 1)
         << " mm, LA surface area " << fmt(units::mm2_to_cm2(area)) << " cm^2 ("
         << fmt(area / m.area_3d_mm2) << " x annulus)\n";
      const TipToAnnulusPlane t = tip_to_annulus_plane(fr);
      os << "  tips      to annulus plane: anterior " << fmt(t.anterior_mm, 1) << " mm, posterior "
         << fmt(t.posterior_mm, 1) << " mm (+ = atrial; plane from "
         << (t.plane_from_landmarks ? "trigones + posterior mid-point" : "least squares") << ")\n";
    } else {
      os << "  leaflets  not observed in this frame\n";
    }
  };
  frame_report(s.end_diastole, "end-diastole");
  frame_report(s.first_closed, "first closed");
  for (const ChordaeRupture& r : s.ruptured_chordae) {
    os << "chordae   ruptured: the marginal chordae inserting at s in [" << fmt(r.s_begin, 3)
       << ", " << fmt(r.s_end, 3) << ") ("
       << (r.s_end <= 0.5     ? "anterior"
           : r.s_begin >= 0.5 ? "posterior"
                              : "both")
       << " leaflet)\n";
  }
  if (s.end_diastole < 0 && s.first_closed < 0) frame_report(0, "frame 0");
  if (!p.images.empty()) {
    const auto& im = p.images.front();
    os << "images    " << p.images.size() << " volume(s), " << im.size[0] << "x" << im.size[1]
       << "x" << im.size[2] << " voxels of " << fmt(im.spacing[0]) << "x" << fmt(im.spacing[1])
       << "x" << fmt(im.spacing[2]) << " mm\n";
  }
  if (p.truth) {
    const VirtualTruth& t = *p.truth;
    os << "hidden    pathology " << pathology_name(t.pathology) << "; ";
    t.parameters.for_each([&](const std::string& n, double v, const char* unit) {
      if (n == "peak_pressure") {
        os << n << " " << fmt(units::mpa_to_mmhg(v), 1) << " mmHg";
      } else {
        os << n << " " << fmt(v, 3) << (std::string(unit) == "1" ? "" : std::string(" ") + unit)
           << "; ";
      }
    });
    os << "\n";
    os << "closed    " << t.closed_frames << "\n";
  }
}

/// The (u, v) grid resolution options shared by the commands that make a valve.
void add_grid_options(CLI::App* cmd, int& ures, int& vres) {
  cmd->add_option("--ures", ures, "grid points around the annulus (even, >= 8)")->default_val(30);
  cmd->add_option("--vres", vres, "grid points from annulus to free edge (>= 3)")->default_val(30);
}

}  // namespace

void refuse_overwrite_path(const fs::path& p, bool force) { refuse_overwrite(p, force); }

nlohmann::json provenance(const Context& ctx) {
  return {{"mvtwin_version", kVersion},
          {"command", ctx.command_line},
          {"created_utc", utc_now_iso8601()}};
}

Patient read_patient_for_run(const fs::path& path, bool use_detected) {
  Patient p = read_patient(path, false);
  if (use_detected) {
    if (!p.detected)
      throw Error(path.string() + " has no detected sequence (run mvtwin detect first)");
    // Detection finds the leaflets, not torn chordae: those stay the patient's known anatomy.
    const std::vector<ChordaeRupture> ruptures = p.sequence.ruptured_chordae;
    p.sequence = *p.detected;
    if (p.sequence.ruptured_chordae.empty()) p.sequence.ruptured_chordae = ruptures;
    p.provenance.source.append("; sequence detected from images (")
        .append(p.detected_by)
        .append(")");
  }
  print_assumed(p, std::cout);
  return p;
}

void register_commands(CLI::App& app, Context& ctx) {
  // ---- phantom ---------------------------------------------------------------------------------
  {
    auto* cmd = app.add_subcommand("phantom", "Make one virtual (synthetic) patient");
    cmd->footer(
        "Example:\n  mvtwin phantom --seed 1 --out patient.h5\n  mvtwin phantom --seed 7 "
        "--pathology functional_mr --out fmr.h5\n"
        "  mvtwin phantom --seed 1 --out p.h5 --simulate-closure   (observed closing frames: a\n"
        "  fine simulation with the hidden parameters plus noise; slow, see --closure-set)");
    auto seed = std::make_shared<std::uint64_t>(1);
    auto out = std::make_shared<std::string>();
    auto pathology = std::make_shared<std::string>();
    auto opts = std::make_shared<VirtualPatientOptions>();
    auto force = std::make_shared<bool>(false);
    cmd->add_option("--seed", *seed, "random seed (same seed, same patient)")->default_val(1);
    cmd->add_option("--out", *out, "patient file to write (HDF5)")->required();
    cmd->add_option("--pathology", *pathology,
                    "normal | prolapse_elongated_chordae | prolapse_ruptured_chordae | "
                    "functional_mr | stiff_leaflets (default: drawn)");
    add_grid_options(cmd, opts->ures, opts->vres);
    cmd->add_flag("--force", *force, "replace an existing file");
    auto closure = std::make_shared<bool>(false);
    auto closure_sets = std::make_shared<std::vector<std::string>>();
    auto noise = std::make_shared<double>(0.5);
    cmd->add_flag("--simulate-closure", *closure,
                  "fill the closing frames by a fine simulation with the hidden parameters");
    cmd->add_option("--closure-set", *closure_sets,
                    "name=value for that simulation (default: ures = vres = 40, 3 layers, "
                    "dt = 0.001 s, linear systems to 1e-3)");
    cmd->add_option("--noise", *noise, "detection-like noise on the simulated surfaces, mm")
        ->default_val(0.5);
    cmd->callback([=, &ctx] {
      ctx.run = [=, &ctx] {
        refuse_overwrite(*out, *force);
        VirtualPatientOptions o = *opts;
        if (!pathology->empty()) o.pathology = pathology_from_name(*pathology);
        o.command = ctx.command_line;
        Patient p = make_virtual_patient(*seed, o);
        if (*closure) {
          forward::VirtualClosureOptions vo;
          vo.noise_mm = *noise;
          for (const auto& a : *closure_sets)
            forward::apply_option(a, &vo.simulation,
                                  "--closure-set: the closing frames are simulated with the "
                                  "patient's hidden parameters");
          std::cout << "simulating the closing frames of " << p.id << " ..." << std::endl;
          forward::simulate_observed_closure(&p, vo);
          std::cout << p.truth->closed_frames << "\n";
        }
        write_patient(*out, p);
        std::cout << "wrote " << *out << ": virtual patient " << p.id << " ("
                  << pathology_name(p.truth->pathology) << ", " << p.sequence.num_frames()
                  << " frames, SYNTHETIC)\n";
        return 0;
      };
    });
  }
  // ---- cohort ----------------------------------------------------------------------------------
  {
    auto* cmd = app.add_subcommand("cohort", "Make many virtual patients (resumable)");
    cmd->footer(
        "Example:\n  mvtwin cohort --n 25 --seed 2026 --out cohort/\n"
        "Patient i has the seed and pathology every command gives it (the pathologies in turn),\n"
        "so mvtwin study cohort --seed 2026 draws the same patients.\n"
        "Existing valid patient files are kept (the run resumes); a patient that fails is\n"
        "reported in cohort.json and the others go on.");
    auto n = std::make_shared<int>(25);
    auto seed = std::make_shared<std::uint64_t>(1);
    auto out = std::make_shared<std::string>();
    auto opts = std::make_shared<VirtualPatientOptions>();
    cmd->add_option("--n", *n, "number of patients")->default_val(25)->check(CLI::Range(1, 100000));
    cmd->add_option("--seed", *seed, "cohort seed")->default_val(1);
    cmd->add_option("--out", *out, "output directory")->required();
    add_grid_options(cmd, opts->ures, opts->vres);
    cmd->callback([=, &ctx] {
      ctx.run = [=, &ctx] {
        std::error_code ec;
        fs::create_directories(*out, ec);
        if (ec) throw Error(*out + ": cannot create directory: " + ec.message());
        nlohmann::json manifest;
        manifest["format"] = "mvtwin-cohort";
        manifest["synthetic"] = true;
        manifest.update(provenance(ctx));
        manifest["seed"] = *seed;
        manifest["n"] = *n;
        manifest["patients"] = nlohmann::json::array();
        int made = 0, kept = 0, failed = 0;
        for (int i = 0; i < *n; ++i) {
          char name[32];
          std::snprintf(name, sizeof name, "patient_%04d.h5", i);
          const fs::path path = fs::path(*out) / name;
          const std::uint64_t s = cohort_member(*seed, i).seed;
          nlohmann::json entry{{"file", name}, {"seed", s}};
          try {
            bool reuse = false;
            if (fs::exists(path)) {
              try {
                const Patient old = read_patient(path, false);
                reuse = old.provenance.seed == s && old.sequence.ures == opts->ures &&
                        old.sequence.vres == opts->vres;
              } catch (const Error&) {
                reuse = false;  // damaged or foreign file: make it again
              }
            }
            Patient p;
            if (reuse) {
              p = read_patient(path, false);
              ++kept;
              entry["status"] = "kept";
            } else {
              VirtualPatientOptions o = *opts;
              o.command = ctx.command_line + "  [patient " + std::to_string(i) + "]";
              p = make_cohort_patient(*seed, i, o);
              write_patient(path, p);
              ++made;
              entry["status"] = "made";
            }
            entry["id"] = p.id;
            entry["pathology"] = std::string(pathology_name(p.truth->pathology));
          } catch (const Error& e) {
            ++failed;
            entry["status"] = "failed";
            entry["error"] = e.what();
            std::cerr << "\nmvtwin cohort: patient " << i << " failed: " << e.what() << "\n";
          }
          manifest["patients"].push_back(entry);
          std::cerr << "\r[cohort] " << (i + 1) << "/" << *n << " (made " << made << ", kept "
                    << kept << ", failed " << failed << ")" << std::flush;
        }
        std::cerr << "\n";
        manifest["made"] = made;
        manifest["kept"] = kept;
        manifest["failed"] = failed;
        const fs::path mpath = fs::path(*out) / "cohort.json";
        write_atomically(mpath, [&](const fs::path& tmp) {
          std::ofstream f(tmp);
          f << manifest.dump(2) << "\n";
          if (!f) throw Error(mpath.string() + ": write failed");
        });
        std::cout << "cohort of " << *n << " virtual patients in " << *out << " (made " << made
                  << ", kept " << kept << ", failed " << failed << "); manifest " << mpath.string()
                  << "\n";
        return failed ? int{kExitFailed} : int{kExitOk};
      };
    });
  }
  // ---- info ------------------------------------------------------------------------------------
  {
    auto* cmd = app.add_subcommand("info", "Human summary of a patient or simulation file");
    cmd->footer("Examples:\n  mvtwin info patient.h5\n  mvtwin info closed.h5");
    auto file = std::make_shared<std::string>();
    cmd->add_option("FILE", *file, "patient or simulation file (HDF5)")->required();
    cmd->callback([=, &ctx] {
      ctx.run = [=] {
        if (mvtwin_file_format(*file) == "mvtwin-simulation") {
          print_simulation_info(read_simulation_file(*file), std::cout);
          return 0;
        }
        const Patient p = read_patient(*file, true);
        print_info(p, std::cout);
        return 0;
      };
    });
  }
  // ---- export ----------------------------------------------------------------------------------
  {
    auto* cmd =
        app.add_subcommand("export", "Export a patient file to VTK for ParaView, or as label maps");
    cmd->footer(
        "Examples:\n  mvtwin export patient.h5 --vtk vtk/\n  paraview vtk/la_surface.pvd "
        "vtk/annulus.pvd vtk/landmarks.pvd\n"
        "  mvtwin export patient.h5 --labelmap seg/ --convention mvseg --voxel 0.8\n"
        "--labelmap writes each frame with a leaflet surface (or --frames I,J) as a NIfTI label "
        "map\n"
        "(leaflets extruded by their thickness, partial-volume boundary noise --boundary-noise, "
        "seeded\n"
        "by --seed) and its papillary tips as a 3D Slicer markups file, ready for mvtwin import.");
    auto file = std::make_shared<std::string>();
    auto dir = std::make_shared<std::string>();
    auto labeldir = std::make_shared<std::string>();
    auto convention = std::make_shared<std::string>("mvtool");
    auto lo = std::make_shared<detection::LabelMapOptions>();
    auto frames = std::make_shared<std::vector<int>>();
    auto force = std::make_shared<bool>(false);
    auto as_sequence = std::make_shared<bool>(false);
    cmd->add_option("FILE", *file, "patient file (HDF5)")->required();
    cmd->add_option("--vtk", *dir, "output directory for VTK");
    cmd->add_flag("--sequence", *as_sequence,
                  "with --labelmap: one 3D+t file, labels.seq.nrrd (3D Slicer's sequence)");
    cmd->add_option("--labelmap", *labeldir, "output directory for label maps and markups");
    cmd->add_option("--convention", *convention, "with --labelmap: mvtool or mvseg")
        ->default_val("mvtool");
    cmd->add_option("--voxel", lo->voxel_mm, "with --labelmap: voxel size, mm")
        ->default_val(lo->voxel_mm);
    cmd->add_option("--boundary-noise", lo->boundary_noise,
                    "with --labelmap: partial-volume noise SD")
        ->default_val(lo->boundary_noise);
    cmd->add_option("--seed", lo->seed, "with --labelmap: seed of the boundary noise")
        ->default_val(lo->seed);
    cmd->add_option("--frames", *frames,
                    "with --labelmap: frame indices (default: every frame with leaflets)")
        ->delimiter(',');
    cmd->add_flag("--force", *force, "write into a directory that already has output files");
    cmd->callback([=, &ctx] {
      ctx.run = [=] {
        if (dir->empty() && labeldir->empty())
          throw Error("export: give --vtk DIR and/or --labelmap DIR");
        const Patient p = read_patient(*file, false);
        if (!dir->empty()) {
          refuse_overwrite(fs::path(*dir) / "la_surface.pvd", *force);
          const auto files = export_patient_vtk(p, *dir);
          std::cout << "wrote " << files.size() << " VTK files to " << *dir
                    << " (open la_surface.pvd, annulus.pvd, landmarks.pvd in ParaView)\n";
        }
        if (!labeldir->empty()) {
          detection::LabelMapOptions o = *lo;
          o.labels = detection::segmentation_labels(*convention);
          std::vector<int> which = *frames;
          if (which.empty())
            for (int f = 0; f < p.sequence.num_frames(); ++f)
              if (p.sequence.frames[f].la_surface) which.push_back(f);
          if (which.empty()) throw Error(*file + ": no frame has a leaflet surface to export");
          fs::create_directories(*labeldir);
          std::string cmdline = "mvtwin import";
          for (int f : which) {
            if (f < 0 || f >= p.sequence.num_frames())
              throw Error("--frames: no frame " + std::to_string(f));
            if (!p.sequence.frames[f].la_surface)
              throw Error(*file + ": frame " + std::to_string(f) + " has no leaflet surface");
          }
          std::vector<ImageVolume> series;
          if (*as_sequence) {
            std::vector<ImageVolume> boxes;
            for (int f : which)
              boxes.push_back(detection::label_map_geometry(p.sequence.frames[f], o));
            o.geometry = detection::union_geometry(boxes);
          }
          for (int f : which) {
            const ValveFrame& fr = p.sequence.frames[f];
            char name[64];
            o.seed = lo->seed + static_cast<std::uint64_t>(f);
            char t[32];
            std::snprintf(t, sizeof t, "%.4f", fr.time_s);
            if (*as_sequence) {
              series.push_back(detection::valve_label_map(fr, o));
              series.back().time_s = fr.time_s;
            } else {
              std::snprintf(name, sizeof name, "frame_%02d.nii.gz", f);
              const fs::path img = fs::path(*labeldir) / name;
              refuse_overwrite(img, *force);
              write_nifti(img, detection::valve_label_map(fr, o));
              cmdline += " --frame " + img.string() + "@" + t;
            }
            std::snprintf(name, sizeof name, "tips_%02d.mrk.json", f);
            const fs::path mk = fs::path(*labeldir) / name;
            refuse_overwrite(mk, *force);
            std::vector<MarkupPoint> pts;
            for (Landmark l :
                 {Landmark::kAnterolateralPapillaryTip, Landmark::kPosteromedialPapillaryTip})
              if (fr.observed(l)) pts.push_back({std::string(name_of_landmark(l)), fr.landmark(l)});
            if (!pts.empty()) {
              write_markups_json(mk, pts);
              cmdline += " --markups " + mk.string() + "@" + t;
            }
          }
          if (*as_sequence) {
            const fs::path seq = fs::path(*labeldir) / "labels.seq.nrrd";
            refuse_overwrite(seq, *force);
            write_image_series(seq, series);
            cmdline += " --sequence " + seq.string();
          }
          std::cout << "wrote " << which.size() << " label map(s) (" << o.labels.describe() << ", "
                    << o.voxel_mm << " mm voxels"
                    << (p.synthetic ? ", SYNTHETIC: from a virtual patient" : "") << ") to "
                    << *labeldir << "\nimport them with:\n  " << cmdline << " --convention "
                    << *convention << " --out imported.h5\n";
        }
        return 0;
      };
    });
  }
  // ---- export-model ----------------------------------------------------------------------------
  {
    auto* cmd = app.add_subcommand("export-model",
                                   "Write the FE scene at end-diastole for ParaView and FEBio");
    cmd->footer(
        "Example:\n  mvtwin export-model patient.h5 --out model/\n"
        "  mvtwin export-model patient.h5 --out model/ --set ures=40 --set clips=0.25,1,0.75,1\n"
        "Writes leaflets.vtu / leaflets_quadratic.vtu (tags, fibres, prescribed flags), "
        "chordae.vtp\n"
        "(rest lengths and laws), pressure_surface.vtp, boundary.csv (pressure profile, papillary\n"
        "tips), annulus_motion.csv and boundary.pvd (prescribed motion), valve.feb (FEBio 4.0).\n"
        "Uses the patient's hidden parameters when it is synthetic, else the defaults; --set as "
        "in\n"
        "mvtwin simulate.");
    auto file = std::make_shared<std::string>();
    auto dir = std::make_shared<std::string>();
    auto opts = std::make_shared<forward::ClosureOptions>();
    auto sets = std::make_shared<std::vector<std::string>>();
    cmd->add_option("FILE", *file, "patient file (HDF5)")->required();
    cmd->add_option("--out", *dir, "output directory")->required();
    add_grid_options(cmd, opts->model.ures, opts->model.vres);
    cmd->add_option("--layers", opts->model.layers, "element layers through the thickness")
        ->default_val(1);
    cmd->add_option("--marginal-chordae", opts->model.marginal_chordae, "marginal chordae count")
        ->default_val(28);
    cmd->add_option("--set", *sets, "name=value for any option or parameter (repeatable)");
    cmd->callback([=, &ctx] {
      ctx.run = [=, &ctx] {
        const Patient p = read_patient(*file, false);
        forward::ClosureOptions o = *opts;
        ValveParameters par;
        if (p.truth) par = p.truth->parameters;
        for (const std::string& a : *sets) forward::apply_setting(a, &o, &par);
        const forward::ClosureScene scene = forward::make_closure_scene(p.sequence, par, o);
        std::ostringstream comment;
        comment << "mvtwin " << kVersion << " export-model of " << p.id
                << (p.synthetic ? " [SYNTHETIC: virtual patient]" : "")
                << "\ncommand: " << ctx.command_line << "\ncreated: " << utc_now_iso8601()
                << "\nparameters:";
        par.for_each([&](const std::string& name, double v, const char* unit) {
          comment << " " << name << "=" << v << " " << unit << ";";
        });
        const auto files = forward::export_scene(scene, o, *dir, comment.str());
        const forward::ValveModel& m = scene.model;
        std::cout << "scene of " << p.id << (p.synthetic ? " [SYNTHETIC]" : "") << ": "
                  << m.mesh.num_elements()
                  << (m.mesh.order == forward::TetOrder::kQuadratic ? " quadratic" : " linear")
                  << " tetrahedra, " << m.mesh.num_nodes() << " nodes, " << scene.chordae.size()
                  << " chordae, " << scene.springs.size() << " clips, " << scene.prescribed.size()
                  << " prescribed nodes, closure over " << fmt(scene.duration(), 3)
                  << " s (simulated); worst element quality " << m.min_quality << " (element "
                  << m.worst_element << "); wrote " << files.size() << " files to " << *dir
                  << " (valve.feb for FEBio)\n";
        return 0;
      };
    });
  }
  // ---- simulate -------------------------------------------------------------------------------
  {
    auto* cmd = app.add_subcommand("simulate", "Simulate the closure of a patient");
    cmd->footer(
        "Examples:\n  mvtwin simulate patient.h5 --out closed.h5 --vtk sim/\n"
        "  mvtwin simulate patient.h5 --out closed.h5 --set dt=0.005 --set contact=off\n"
        "  mvtwin simulate patient.h5 --out closed.h5 --solver cholmod-supernodal --set "
        "pcg_tolerance=1e-8   (a\n  factorization every step, linear systems solved to 1e-8: "
        "a reference run)\n"
        "Uses the patient's hidden parameters when it is synthetic, else the defaults.\n"
        "Exit status 4 when the simulation fails (the result file says why).");
    auto file = std::make_shared<std::string>();
    auto dir = std::make_shared<std::string>();
    auto out = std::make_shared<std::string>();
    auto force = std::make_shared<bool>(false);
    auto opts = std::make_shared<forward::ClosureOptions>();
    auto newton = std::make_shared<int>(1);
    cmd->add_option("--out", *out, "result file (HDF5)");
    auto use_detected = std::make_shared<bool>(false);
    cmd->add_flag("--use-detected", *use_detected,
                  "simulate the sequence detected from the images (mvtwin detect)");
    cmd->add_flag("--force", *force, "replace an existing result file");
    cmd->add_option("FILE", *file, "patient file (HDF5)")->required();
    cmd->add_option("--vtk", *dir, "directory for the ParaView series");
    add_grid_options(cmd, opts->model.ures, opts->model.vres);
    cmd->add_option("--dt", opts->dt, "time step, s")->default_val(0.01);
    cmd->add_option("--newton", *newton, "Newton iterations per step (1 = one linearization)")
        ->default_val(1);
    const std::string default_solver = forward::name(forward::ClosureOptions{}.solver.kind);
    auto solver = std::make_shared<std::string>(default_solver);
    cmd->add_option("--solver", *solver,
                    "reused-factor-pcg | cholmod-supernodal | cholmod-simplicial | eigen-ldlt")
        ->default_val(default_solver);
    auto no_contact = std::make_shared<bool>(false);
    cmd->add_flag("--no-contact", *no_contact, "switch self-contact off");
    auto sets = std::make_shared<std::vector<std::string>>();
    cmd->add_option("--set", *sets,
                    "name=value for any option or parameter (repeatable), e.g. --set dt=0.005 "
                    "--set peak_pressure_mmhg=100");
    cmd->callback([=, &ctx] {
      ctx.run = [=] {
        const Patient p = read_patient_for_run(*file, *use_detected);
        forward::ClosureOptions o = *opts;
        if (!forward::parse_linear_solver(*solver, &o.solver.kind))
          throw Error("unknown solver '" + *solver + "'");
        o.contact.enabled = !*no_contact;
        o.newton_iterations = *newton;
        ValveParameters par;
        if (p.truth) par = p.truth->parameters;
        for (const std::string& a : *sets) forward::apply_setting(a, &o, &par);
        if (o.record_every == 0) o.record_every = std::max(1, static_cast<int>(0.1 / o.dt));
        if (!out->empty()) refuse_overwrite(*out, *force);
        std::cout << "simulating " << p.id << (p.synthetic ? " [SYNTHETIC]" : "") << ": "
                  << o.model.ures << " x " << o.model.vres << " grid, " << o.model.layers
                  << " layer(s), dt " << o.dt << " s, contact "
                  << (o.contact.enabled ? "on" : "off") << std::endl;
        o.progress = progress_line("  closure");
        const forward::ClosureResult r = forward::simulate_closure(p.sequence, par, o);
        std::cout << r.summary.brief_report() << "\n";
        for (const auto& s : r.samples) {
          std::cout << "  t = " << fmt(s.time_s, 2) << " s: tips to annulus plane, anterior "
                    << fmt(s.anterior_tip_mm) << " mm, posterior " << fmt(s.posterior_tip_mm)
                    << " mm; orifice " << fmt(s.orifice_area_mm2, 1) << " of "
                    << fmt(s.annulus_area_mm2, 0) << " mm^2 (" << s.orifice_components << " opening"
                    << (s.orifice_components == 1 ? "" : "s") << "); closest contact "
                    << fmt(s.min_contact_distance_mm, 2) << " mm\n";
        }
        if (!r.samples.empty()) {
          const auto& a = r.samples.front();
          const auto& b = r.samples.back();
          std::cout << "closure: regurgitant orifice " << fmt(a.orifice_area_mm2, 1) << " -> "
                    << fmt(b.orifice_area_mm2, 1) << " mm^2 ("
                    << fmt(100.0 * b.orifice_area_mm2 / std::max(b.annulus_area_mm2, 1e-9), 1)
                    << " % of the annulus opening); closest contact "
                    << fmt(r.summary.min_contact_distance_mm, 2) << " mm\n";
        }
        for (size_t c = 0; c < r.clip_gap_clipped_mm.size(); ++c) {
          std::cout << "clip " << c + 1 << ": atrial surfaces " << fmt(r.clip_gap_clipped_mm[c], 2)
                    << " mm apart after clipping";
          if (c < r.clip_gap_end_mm.size())
            std::cout << ", " << fmt(r.clip_gap_end_mm[c], 2) << " mm at the end";
          std::cout << "\n";
        }
        if (!out->empty()) {
          write_simulation_result(*out, r, o, par, p, *file, ctx);
          std::cout << "wrote " << *out << " (mvtwin info " << *out << ")\n";
        }
        if (!dir->empty()) {
          const auto files = forward::export_closure_vtk(r, *dir);
          std::cout << "wrote " << files.size() << " files to " << *dir
                    << " (open simulation.pvd and leaflets_end.vtu)\n";
        }
        return r.summary.converged() ? kExitOk : kExitFailed;
      };
    });
  }
  // ---- distance --------------------------------------------------------------------------------
  {
    auto* cmd = app.add_subcommand("distance", "Point-to-mesh distance between two LA surfaces");
    cmd->footer(
        "Example:\n  mvtwin distance 008_gt.h5 008_pred.h5\n  mvtwin distance closed.h5 "
        "patient.h5\n"
        "A and B are patient files or simulation results (their end surface). Patient frames\n"
        "default to the first closed frame (else frame 0); distances go from the vertices of\n"
        "one surface to the triangles of the other, both ways.");
    auto a = std::make_shared<std::string>(), b = std::make_shared<std::string>();
    auto fa = std::make_shared<int>(-1), fb = std::make_shared<int>(-1);
    cmd->add_option("A", *a, "first patient or simulation file")->required();
    cmd->add_option("B", *b, "second patient or simulation file")->required();
    cmd->add_option("--frame-a", *fa, "frame of A (default: first closed, else 0)");
    cmd->add_option("--frame-b", *fb, "frame of B (default: first closed, else 0)");
    cmd->callback([=, &ctx] {
      ctx.run = [=] {
        auto surface = [](const std::string& file, int frame) {
          if (mvtwin_file_format(file) == "mvtwin-simulation") {
            const SimulationRecord r = read_simulation_file(file);
            if (r.la_surface.empty()) throw Error(file + ": the simulation recorded no surface");
            return r.la_surface.back().triangulate();
          }
          const Patient p = read_patient(file, false);
          const ValveSequence& s = p.sequence;
          if (frame < 0) frame = s.first_closed >= 0 ? s.first_closed : 0;
          if (frame >= s.num_frames()) {
            throw Error(file + ": frame " + std::to_string(frame) + " does not exist (" +
                        std::to_string(s.num_frames()) + " frames)");
          }
          if (!s.frames[frame].la_surface) {
            throw Error(file + ": frame " + std::to_string(frame) + " has no leaflet surface");
          }
          return s.frames[frame].la_surface->triangulate();
        };
        const SymmetricDistance d = symmetric_surface_distance(surface(*a, *fa), surface(*b, *fb));
        auto line = [](const char* what, const DistanceStats& x) {
          std::cout << what << fmt(x.mean) << " +- " << fmt(x.sd) << " mm (95th pct " << fmt(x.p95)
                    << ", max " << fmt(x.max) << ", n=" << x.count << ")\n";
        };
        line("A -> B:    ", d.a_to_b);
        line("B -> A:    ", d.b_to_a);
        line("symmetric: ", d.symmetric);
        return 0;
      };
    });
  }
}

}  // namespace mvtwin::tools
