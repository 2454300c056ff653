// mvtwin train-detector and mvtwin detect: valve anatomy from 3D+t TEE (detection/valve_detector.h).
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "commands.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/point_to_mesh_distance.h"
#include "mvtwin/core/version.h"
#include "mvtwin/detection/valve_detector.h"

namespace mvtwin::tools {
namespace fs = std::filesystem;

namespace {

std::vector<fs::path> patient_files(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw Error(dir.string() + ": not a directory");
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file() && e.path().extension() == ".h5") out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

/// Mean symmetric point-to-mesh distance of two valve frames' LA surfaces, mm (NaN without both).
double frame_surface_error(const ValveFrame& a, const ValveFrame& b) {
  if (!a.la_surface || !b.la_surface) return std::numeric_limits<double>::quiet_NaN();
  return symmetric_surface_distance(a.la_surface->triangulate(), b.la_surface->triangulate()).symmetric.mean;
}

}  // namespace

void register_detect(CLI::App& app, Context& ctx) {
  {
    auto* cmd = app.add_subcommand("train-detector", "Train the valve detector on a cohort with images");
    cmd->footer(
        "Example:\n  mvtwin train-detector --cohort train/ --out detector.yml.gz\n"
        "Every patient file in the cohort directory with images (mvtwin render-tee) and an\n"
        "observed valve in the same frames is used: each frame with landmarks and an LA surface\n"
        "is one training volume.");
    auto cohort = std::make_shared<std::string>();
    auto out = std::make_shared<std::string>();
    auto force = std::make_shared<bool>(false);
    auto o = std::make_shared<detection::DetectorOptions>();
    cmd->add_option("--cohort", *cohort, "directory of patient files (HDF5) with images")->required();
    cmd->add_option("--out", *out, "model file (.yml.gz)")->required();
    cmd->add_flag("--force", *force, "replace an existing model file");
    cmd->add_option("--trees", o->trees, "trees per forest")->default_val(o->trees);
    cmd->add_option("--samples", o->samples_per_volume, "training samples per volume and detector")
        ->default_val(o->samples_per_volume);
    cmd->add_option("--seed", o->seed, "random seed")->default_val(o->seed);
    cmd->callback([=, &ctx] {
      ctx.run = [=, &ctx] {
        refuse_overwrite_path(*out, *force);
        std::vector<Patient> patients;
        std::vector<std::string> used;
        for (const fs::path& f : patient_files(*cohort)) {
          try {
            Patient p = read_patient(f, true);
            if (p.images.size() != p.sequence.frames.size()) {
              std::cout << "  skipped " << f.filename().string() << ": "
                        << (p.images.empty() ? "no images (run mvtwin render-tee)"
                                             : "images and frames differ in number")
                        << "\n";
              continue;
            }
            used.push_back(p.id);
            patients.push_back(std::move(p));
          } catch (const Error& e) {
            std::cout << "  skipped " << f.filename().string() << ": " << e.what() << "\n";
          }
        }
        std::vector<detection::TrainingVolume> data;
        for (const Patient& p : patients)
          for (std::size_t f = 0; f < p.images.size(); ++f)
            if (p.sequence.frames[f].la_surface) data.push_back({&p.images[f], &p.sequence.frames[f]});
        std::cout << "training on " << data.size() << " volumes of " << patients.size() << " patients"
                  << std::endl;
        const auto t0 = std::chrono::steady_clock::now();
        const detection::ValveDetector d = detection::ValveDetector::train(
            data, *o, [](const std::string& s) { std::cout << "  " << s << std::endl; });
        std::string ids;
        for (const auto& id : used) {
          if (!ids.empty()) ids += ',';
          ids += id;
        }
        d.save(*out, {{"mvtwin_version", std::string(kVersion)},
                      {"command", ctx.command_line},
                      {"created_utc", utc_now_iso8601()},
                      {"training_patients", ids},
                      {"training_volumes", std::to_string(data.size())}});
        std::cout << "trained in "
                  << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()
                  << " s; shape model " << d.shape().modes() << " modes on a " << d.shape().ures()
                  << " x " << d.shape().vres() << " grid\nwrote " << *out << "\n";
        return 0;
      };
    });
  }
  {
    auto* cmd = app.add_subcommand("detect", "Detect the valve in a patient's images");
    cmd->footer(
        "Example:\n  mvtwin detect patient.h5 --model detector.yml.gz\n"
        "Detects landmarks, papillary tips and the LA surface in every frame (tracked) and writes\n"
        "them into the patient file as /detected, beside the stored sequence (never over it);\n"
        "--out writes a copy instead. Then: mvtwin simulate|calibrate|clip ... --use-detected.\n"
        "When the file holds a known valve in the same frames, the error is reported.");
    auto file = std::make_shared<std::string>();
    auto model = std::make_shared<std::string>();
    auto out = std::make_shared<std::string>();
    auto force = std::make_shared<bool>(false);
    cmd->add_option("FILE", *file, "patient file (HDF5) with images")->required();
    cmd->add_option("--model", *model, "detector model (mvtwin train-detector)")->required();
    cmd->add_option("--out", *out, "write the patient with its detection here instead of updating FILE");
    cmd->add_flag("--force", *force, "replace an earlier detection, or an existing --out");
    cmd->callback([=, &ctx] {
      ctx.run = [=, &ctx] {
        Patient p = read_patient(*file, true);
        if (p.images.empty()) throw Error(*file + " holds no images (mvtwin render-tee, or import them)");
        const fs::path dest = out->empty() ? fs::path(*file) : fs::path(*out);
        if (!out->empty()) refuse_overwrite_path(dest, *force);
        if (out->empty() && p.detected && !*force)
          throw Error(*file + " already holds a detection (--force replaces it, --out writes a copy)");
        const detection::ValveDetector d = detection::ValveDetector::load(*model);
        std::vector<detection::DetectionInfo> info;
        const std::vector<ValveFrame> frames = d.detect_sequence(p.images, &info);
        ValveSequence seq;
        seq.ures = d.shape().ures();
        seq.vres = d.shape().vres();
        seq.frames = frames;
        seq.end_diastole = p.sequence.end_diastole;
        seq.first_closed = p.sequence.first_closed;
        if (p.images.size() != p.sequence.frames.size()) {
          seq.end_diastole = -1;
          seq.first_closed = -1;
        }
        double total_s = 0, err = 0;
        int nerr = 0;
        for (std::size_t f = 0; f < frames.size(); ++f) {
          total_s += info[f].seconds;
          if (p.images.size() == p.sequence.frames.size()) {
            const double e = frame_surface_error(frames[f], p.sequence.frames[f]);
            if (std::isfinite(e)) {
              err += e;
              ++nerr;
            }
          }
        }
        p.detected = seq;
        p.detected_by = "model " + *model + "; " + ctx.command_line;
        write_patient(dest, p);
        std::cout << "detected " << frames.size() << " frames of " << p.id << (p.synthetic ? " [SYNTHETIC]" : "")
                  << " in " << total_s << " s (" << total_s / static_cast<double>(frames.size())
                  << " s per volume)\n";
        if (nerr > 0)
          std::cout << "  surface error against the stored valve: " << err / nerr << " mm (mean over "
                    << nerr << " frames)\n";
        std::cout << "wrote /detected into " << dest.string() << "\n";
        return 0;
      };
    });
  }
}

}  // namespace mvtwin::tools
