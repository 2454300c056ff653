// mvtwin export (tools/export.h).
#include "export.h"

#include <cstdio>
#include <filesystem>
#include <iostream>

#include "exit_codes.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/image_io.h"
#include "mvtwin/core/markups.h"
#include "mvtwin/core/nifti.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/patient_vtk.h"

namespace mvtwin::tools {
namespace fs = std::filesystem;
namespace {

std::string name_of_landmark(Landmark l) {
  std::string s(name(l));
  for (char& c : s)
    if (c == '_') c = ' ';
  return s;
}

}  // namespace

int run_export(const ExportArgs& a) {
  if (a.vtk.empty() && a.labelmap.empty())
    throw Error("export: give --vtk DIR and/or --labelmap DIR");
  const Patient p = read_patient(a.file, false);
  if (!a.vtk.empty()) {
    refuse_overwrite(fs::path(a.vtk) / "la_surface.pvd", a.force);
    const auto files = export_patient_vtk(p, a.vtk);
    std::cout << "wrote " << files.size() << " VTK files to " << a.vtk
              << " (open la_surface.pvd, annulus.pvd, landmarks.pvd in ParaView)\n";
  }
  if (!a.labelmap.empty()) {
    detection::LabelMapOptions o = a.label_map;
    o.labels = detection::segmentation_labels(a.convention);
    std::vector<int> which = a.frames;
    if (which.empty())
      for (int f = 0; f < p.sequence.num_frames(); ++f)
        if (p.sequence.frames[f].la_surface) which.push_back(f);
    if (which.empty()) throw Error(a.file + ": no frame has a leaflet surface to export");
    fs::create_directories(a.labelmap);
    std::string cmdline = "mvtwin import";
    for (int f : which) {
      if (f < 0 || f >= p.sequence.num_frames())
        throw Error("--frames: no frame " + std::to_string(f));
      if (!p.sequence.frames[f].la_surface)
        throw Error(a.file + ": frame " + std::to_string(f) + " has no leaflet surface");
    }
    std::vector<ImageVolume> series;
    if (a.sequence) {
      std::vector<ImageVolume> boxes;
      for (int f : which) boxes.push_back(detection::label_map_geometry(p.sequence.frames[f], o));
      o.geometry = detection::union_geometry(boxes);
    }
    for (int f : which) {
      const ValveFrame& fr = p.sequence.frames[f];
      char name[64];
      o.seed = a.label_map.seed + static_cast<std::uint64_t>(f);
      char t[32];
      std::snprintf(t, sizeof t, "%.4f", fr.time_s);
      if (a.sequence) {
        series.push_back(detection::valve_label_map(fr, o));
        series.back().time_s = fr.time_s;
      } else {
        std::snprintf(name, sizeof name, "frame_%02d.nii.gz", f);
        const fs::path img = fs::path(a.labelmap) / name;
        refuse_overwrite(img, a.force);
        write_nifti(img, detection::valve_label_map(fr, o));
        cmdline += " --frame " + img.string() + "@" + t;
      }
      std::snprintf(name, sizeof name, "tips_%02d.mrk.json", f);
      const fs::path mk = fs::path(a.labelmap) / name;
      refuse_overwrite(mk, a.force);
      std::vector<MarkupPoint> pts;
      for (Landmark l :
           {Landmark::kAnterolateralPapillaryTip, Landmark::kPosteromedialPapillaryTip})
        if (fr.observed(l)) pts.push_back({std::string(name_of_landmark(l)), fr.landmark(l)});
      if (!pts.empty()) {
        write_markups_json(mk, pts);
        cmdline += " --markups " + mk.string() + "@" + t;
      }
    }
    if (a.sequence) {
      const fs::path seq = fs::path(a.labelmap) / "labels.seq.nrrd";
      refuse_overwrite(seq, a.force);
      write_image_series(seq, series);
      cmdline += " --sequence " + seq.string();
    }
    std::cout << "wrote " << which.size() << " label map(s) (" << o.labels.describe() << ", "
              << o.voxel_mm << " mm voxels"
              << (p.synthetic ? ", SYNTHETIC: from a virtual patient" : "") << ") to " << a.labelmap
              << "\nimport them with:\n  " << cmdline << " --convention " << a.convention
              << " --out imported.h5\n";
  }
  return kExitOk;
}

void register_export(CLI::App& app, Context& ctx) {
  auto* cmd =
      app.add_subcommand("export", "Export a patient file to VTK for ParaView, or as label maps");
  cmd->footer(
      "Examples:\n  mvtwin export patient.h5 --vtk vtk/\n  paraview vtk/la_surface.pvd "
      "vtk/annulus.pvd vtk/landmarks.pvd\n"
      "  mvtwin export observed.h5 --labelmap seg/ --frames 11,15\n"
      "  mvtwin export observed.h5 --labelmap seg_seq/ --sequence --frames 11,15 --convention "
      "mvseg\n"
      "--labelmap writes each frame with a leaflet surface (or --frames I,J) as a NIfTI label "
      "map\n"
      "(leaflets extruded by their thickness, partial-volume boundary noise --boundary-noise, "
      "seeded\n"
      "by --seed) and its papillary tips as a 3D Slicer markups file, ready for mvtwin import.");
  auto a = std::make_shared<ExportArgs>();
  cmd->add_option("FILE", a->file, "patient file (HDF5)")->required();
  cmd->add_option("--vtk", a->vtk, "output directory for VTK");
  cmd->add_flag("--sequence", a->sequence,
                "with --labelmap: one 3D+t file, labels.seq.nrrd (3D Slicer's sequence)");
  cmd->add_option("--labelmap", a->labelmap, "output directory for label maps and markups");
  cmd->add_option("--convention", a->convention, "with --labelmap: mvtool or mvseg")
      ->default_val("mvtool");
  cmd->add_option("--voxel", a->label_map.voxel_mm, "with --labelmap: voxel size, mm")
      ->default_val(a->label_map.voxel_mm);
  cmd->add_option("--boundary-noise", a->label_map.boundary_noise,
                  "with --labelmap: partial-volume noise SD")
      ->default_val(a->label_map.boundary_noise);
  cmd->add_option("--seed", a->label_map.seed, "with --labelmap: seed of the boundary noise")
      ->default_val(a->label_map.seed);
  cmd->add_option("--frames", a->frames,
                  "with --labelmap: frame indices (default: every frame with leaflets)")
      ->delimiter(',');
  cmd->add_flag("--force", a->force, "write into a directory that already has output files");
  run_on_parse(cmd, ctx, a, run_export);
}

}  // namespace mvtwin::tools
