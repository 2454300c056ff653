// mvtwin render-tee: synthetic 3D+t TEE of a patient's valve sequence (detection/tee_renderer.h),
// stored in the patient file and exported for 3D Slicer, with PNG slices to look at.
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>

#include <CLI/CLI.hpp>
#include <Eigen/LU>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "exit_codes.h"
#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/image_io.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/version.h"
#include "mvtwin/detection/tee_renderer.h"
#include "progress.h"
#include "render_tee.h"

namespace mvtwin::tools {
namespace fs = std::filesystem;

/// A slice through the volume's centre (axis 0: lateral-beam plane, 1: elevation-beam plane,
/// 2: across the beam at the valve) as an 8-bit image, the beam running downwards, with the
/// frame's LA surface points within half a voxel of the slice drawn over it when `overlay`.
cv::Mat slice_image(const ImageVolume& im, int axis, const ValveFrame* overlay, int scale) {
  const int n0 = im.size[0], n1 = im.size[1], n2 = im.size[2];
  const int c = im.size[axis] / 2;
  // Rows run along the beam (z) for the two long-axis views, along elevation (y) otherwise.
  const int rows = axis == 2 ? n1 : n2, cols = axis == 0 ? n1 : n0;
  cv::Mat m(rows, cols, CV_8UC1);
  for (int r = 0; r < rows; ++r) {
    for (int q = 0; q < cols; ++q) {
      int i = 0, j = 0, k = 0;
      if (axis == 0) {
        i = c;
        j = q;
        k = r;
      } else if (axis == 1) {
        i = q;
        j = c;
        k = r;
      } else {
        i = q;
        j = r;
        k = c;
      }
      m.at<unsigned char>(r, q) =
          static_cast<unsigned char>(std::clamp(im.at(i, j, k), 0.0f, 255.0f));
    }
  }
  cv::Mat big;
  cv::resize(m, big, cv::Size(cols * scale, rows * scale), 0, 0, cv::INTER_LINEAR);
  cv::Mat rgb;
  cv::cvtColor(big, rgb, cv::COLOR_GRAY2BGR);
  if (overlay && overlay->la_surface) {
    const Eigen::Matrix3d to_index =
        Eigen::Matrix3d(im.direction * im.spacing.asDiagonal()).inverse();
    const auto& P = overlay->la_surface->points();
    for (Eigen::Index p = 0; p < P.rows(); ++p) {
      const Eigen::Vector3d x = to_index * (P.row(p).transpose() - im.origin);
      if (std::abs(x[axis] - c) > 0.5) continue;
      const double col = axis == 0 ? x[1] : x[0], row = axis == 2 ? x[1] : x[2];
      cv::circle(
          rgb,
          cv::Point(static_cast<int>((col + 0.5) * scale), static_cast<int>((row + 0.5) * scale)),
          std::max(1, scale / 2), cv::Scalar(40, 40, 230), cv::FILLED);
    }
  }
  return rgb;
}

int run_render_tee(const RenderTeeArgs& a) {
  Patient p = read_patient(a.file, true);
  const fs::path dest = a.out.empty() ? fs::path(a.file) : fs::path(a.out);
  if (!a.out.empty()) refuse_overwrite(dest, a.force);
  if (a.out.empty() && !p.images.empty() && !a.force)
    throw Error(a.file + " already holds " + std::to_string(p.images.size()) +
                " image volumes (--force replaces them, --out writes a copy)");
  const detection::TeeGeometry g = detection::tee_geometry(p.sequence, a.render);
  std::cout << "rendering " << p.sequence.num_frames() << " frames of " << p.id
            << (p.synthetic ? " [SYNTHETIC]" : "") << ": " << g.grid.size[0] << "^3 voxels of "
            << a.render.voxel_mm << " mm, noise " << a.render.noise << ", speckle "
            << a.render.speckle << ", drop-outs " << a.render.dropout_fraction << ", seed "
            << a.render.seed << std::endl;
  std::vector<ImageVolume> volumes;
  const auto t0 = std::chrono::steady_clock::now();
  for (int f = 0; f < p.sequence.num_frames(); ++f) {
    volumes.push_back(detection::render_tee_frame(p.sequence, f, g, a.render));
    count_line("  frame " + std::to_string(f + 1) + "/" + std::to_string(p.sequence.num_frames()),
               f + 1 == p.sequence.num_frames());
  }
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::cout << "  " << s << " s (" << s / p.sequence.num_frames() << " s per volume)\n";
  p.images = volumes;
  // The file says what made its images (the patient's own provenance stays as it was).
  std::ostringstream made;
  made << "; images: synthetic TEE by '" << a.command_line << "' (voxel_mm=" << a.render.voxel_mm
       << " axial_psf_mm=" << a.render.axial_psf_mm << " lateral_psf_mm=" << a.render.lateral_psf_mm
       << " noise=" << a.render.noise << " speckle=" << a.render.speckle
       << " dropout=" << a.render.dropout_fraction
       << " attenuation_db_per_mm=" << a.render.attenuation_db_per_mm
       << " probe_jitter_deg=" << a.render.probe_jitter_deg << " seed=" << a.render.seed
       << ", mvtwin " << kVersion << ")";
  p.provenance.source += made.str();
  write_patient(dest, p);
  std::cout << "wrote " << volumes.size() << " volumes into " << dest.string() << " (/images)\n";
  if (!a.export_dir.empty()) {
    create_output_directory(a.export_dir);
    const fs::path seq = fs::path(a.export_dir) / (p.id + "_tee.seq.nrrd");
    write_image_series(seq, volumes);
    std::cout << "wrote " << seq.string() << " (3D Slicer: drag and drop; a volume sequence)\n";
  }
  if (!a.png.empty()) {
    create_output_directory(a.png);
    const int scale = std::max(1, static_cast<int>(std::lround(3.0 * a.render.voxel_mm)));
    for (int f : {p.sequence.end_diastole, p.sequence.first_closed}) {
      if (f < 0) continue;
      const char* phase = f == p.sequence.end_diastole ? "ed" : "closed";
      for (int axis = 0; axis < 3; ++axis) {
        for (bool overlay : {false, true}) {
          const cv::Mat m =
              slice_image(volumes[f], axis, overlay ? &p.sequence.frames[f] : nullptr, scale);
          const std::string name = p.id + "_" + phase + "_" + std::string("xyz").substr(axis, 1) +
                                   (overlay ? "_overlay" : "") + ".png";
          const fs::path path = fs::path(a.png) / name;
          write_atomically(path, [&](const fs::path& tmp) {
            if (!cv::imwrite(tmp.string() + ".png", m))
              throw Error(path.string() + ": cannot write PNG");
            fs::rename(tmp.string() + ".png", tmp);
          });
        }
      }
    }
    std::cout << "wrote PNG slices to " << a.png << "\n";
  }
  return kExitOk;
}

void register_render_tee(CLI::App& app, Context& ctx) {
  auto* cmd = app.add_subcommand("render-tee", "Synthetic 3D+t TEE of a patient's valve sequence");
  cmd->footer(
      "Examples:\n"
      "  mvtwin render-tee observed.h5 --export tee/ --png tee/ --axial-psf 0.5 --lateral-psf 2.2"
      "   # wider beams: 4x faster\n"
      "  mvtwin render-tee observed.h5 --out observed_tee.h5   # long: the default beams\n"
      "Renders every frame as an ultrasound-like volume (pyramidal sector from a probe behind the\n"
      "left atrium, speckle, PSF, attenuation, drop-outs, noise) and stores the volumes in the\n"
      "patient file (/images; --out to write a copy instead). --export writes a 3D Slicer\n"
      "sequence (.seq.nrrd); --png writes slices through the end-diastolic and first closed\n"
      "frames, with the true leaflet surface dotted in red (_overlay.png).");
  auto a = std::make_shared<RenderTeeArgs>();
  cmd->add_option("FILE", a->file, "patient file (HDF5)")->required();
  cmd->add_option("--out", a->out, "write the patient with its TEE here instead of updating FILE");
  cmd->add_option("--export", a->export_dir,
                  "directory for the 3D Slicer sequence (<id>_tee.seq.nrrd)");
  cmd->add_option("--png", a->png, "directory for PNG slices");
  cmd->add_flag("--force", a->force, "replace images already in the file, or an existing --out");
  cmd->add_option("--voxel", a->render.voxel_mm, "voxel size, mm")->default_val(a->render.voxel_mm);
  cmd->add_option("--axial-psf", a->render.axial_psf_mm,
                  "point-spread SD along the beam, mm (coarser renders faster)")
      ->default_val(a->render.axial_psf_mm);
  cmd->add_option("--lateral-psf", a->render.lateral_psf_mm,
                  "point-spread SD across the beam at the probe depth, mm (grows with depth)")
      ->default_val(a->render.lateral_psf_mm);
  cmd->add_option("--noise", a->render.noise, "electronic noise SD (relative to a leaflet's echo)")
      ->default_val(a->render.noise);
  cmd->add_option("--speckle", a->render.speckle, "speckle, 0 (none) to 1 (fully developed)")
      ->default_val(a->render.speckle);
  cmd->add_option("--dropout", a->render.dropout_fraction, "fraction of beams with a drop-out")
      ->default_val(a->render.dropout_fraction);
  cmd->add_option("--attenuation", a->render.attenuation_db_per_mm, "dB/mm after gain compensation")
      ->default_val(a->render.attenuation_db_per_mm);
  cmd->add_option("--probe-jitter", a->render.probe_jitter_deg,
                  "variation of the probe's pose between patients, degrees (0: the standard view)")
      ->default_val(a->render.probe_jitter_deg);
  cmd->add_option("--seed", a->render.seed, "random seed (speckle, noise, drop-outs)")
      ->default_val(a->render.seed);
  run_on_parse(cmd, ctx, a, run_render_tee);
}

}  // namespace mvtwin::tools
