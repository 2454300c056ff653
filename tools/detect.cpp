// mvtwin train-detector and mvtwin detect: valve anatomy from 3D+t TEE
// (detection/valve_detector.h).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "detect.h"
#include "exit_codes.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/version.h"
#include "mvtwin/detection/valve_detector.h"
#include "mvtwin/studies/virtual_tee.h"
#include "output_files.h"

namespace mvtwin::tools {
namespace fs = std::filesystem;

namespace {

std::string json_list(const std::vector<double>& v) {
  std::string s;
  for (double x : v) s += (s.empty() ? "" : ",") + std::to_string(x);
  return s;
}

std::vector<fs::path> patient_files(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw Error(dir.string() + ": not a directory");
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file() && e.path().extension() == ".h5") out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

int run_train_detector(const TrainDetectorArgs& a) {
  if (a.cohort.empty() == (a.n_virtual == 0))
    throw Error("train-detector: give --cohort DIR or --virtual N");
  refuse_overwrite(a.out, a.force);
  if (a.n_virtual > 0) {
    if (const std::string e = a.render.invalid(); !e.empty()) throw Error("train-detector: " + e);
    std::vector<std::uint64_t> seeds;
    for (int i = 0; i < a.n_virtual; ++i)
      seeds.push_back(studies::virtual_cohort_seed(a.cohort_seed, i));
    const studies::VirtualTrainingResult r = studies::train_on_virtual_cohort(
        seeds, studies::VirtualTeeTruth(a.truth_sets), a.render, a.train_noise, a.detector, a.jobs,
        fs::path(a.cache), [](const std::string& line) { std::cout << line << std::endl; });
    std::string ids;
    for (const auto& id : r.patients) ids += (ids.empty() ? "" : ",") + id;
    std::ostringstream render;
    render << "voxel_mm=" << a.render.voxel_mm << " axial_psf_mm=" << a.render.axial_psf_mm
           << " lateral_psf_mm=" << a.render.lateral_psf_mm
           << " probe_jitter_deg=" << a.render.probe_jitter_deg
           << " noise=" << json_list(a.train_noise) << " speckle=" << a.render.speckle
           << " dropout=" << a.render.dropout_fraction;
    r.detector.save(a.out, {{"mvtwin_version", std::string(kVersion)},
                            {"command", a.command_line},
                            {"created_utc", utc_now_iso8601()},
                            {"training_patients", ids + " (synthetic)"},
                            {"training_render", render.str()},
                            {"training_volumes", std::to_string(r.volumes)}});
    std::cout << "shape model " << r.detector.shape().modes() << " modes on a "
              << r.detector.shape().ures() << " x " << r.detector.shape().vres() << " grid\nwrote "
              << a.out << "\n";
    return kExitOk;
  }
  std::vector<Patient> patients;
  std::vector<std::string> used;
  for (const fs::path& f : patient_files(a.cohort)) {
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
      data, a.detector, [](const std::string& s) { std::cout << "  " << s << std::endl; });
  std::string ids;
  for (const auto& id : used) {
    if (!ids.empty()) ids += ',';
    ids += id;
  }
  d.save(a.out, {{"mvtwin_version", std::string(kVersion)},
                 {"command", a.command_line},
                 {"created_utc", utc_now_iso8601()},
                 {"training_patients", ids},
                 {"training_volumes", std::to_string(data.size())}});
  std::cout << "trained in "
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()
            << " s; shape model " << d.shape().modes() << " modes on a " << d.shape().ures()
            << " x " << d.shape().vres() << " grid\nwrote " << a.out << "\n";
  return kExitOk;
}

int run_detect(const DetectArgs& a) {
  Patient p = read_patient(a.file, true);
  if (p.images.empty())
    throw Error(a.file + " holds no images (mvtwin render-tee, or import them)");
  const fs::path dest = a.out.empty() ? fs::path(a.file) : fs::path(a.out);
  if (!a.out.empty()) refuse_overwrite(dest, a.force);
  if (a.out.empty() && p.detected && !a.force)
    throw Error(a.file + " already holds a detection (--force replaces it, --out writes a copy)");
  const detection::ValveDetector d = detection::ValveDetector::load(a.model);
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
  p.detected = seq;
  p.detected_by = "model " + a.model + "; " + a.command_line;
  write_patient(dest, p);
  double total_s = 0;
  for (const auto& i : info) total_s += i.seconds;
  std::cout << "detected " << frames.size() << " frames of " << p.id
            << (p.synthetic ? " [SYNTHETIC]" : "") << " in " << total_s << " s ("
            << total_s / static_cast<double>(frames.size()) << " s per volume)\n";
  // Against the valve stored in the file (for a virtual patient: its truth), when it has
  // the same frames.
  nlohmann::json report{{"patient_id", p.id},
                        {"synthetic", p.synthetic},
                        {"model", a.model},
                        {"frames", frames.size()},
                        {"s_per_volume", total_s / static_cast<double>(frames.size())},
                        {"provenance", provenance(a.command_line)}};
  if (p.images.size() == p.sequence.frames.size()) {
    nlohmann::json run{{"frames", studies::detection_errors(p, frames, info)}};
    const nlohmann::json s = studies::summarize_detections({&run});
    if (s["frames"].get<int>() > 0) {
      std::printf(
          "  against the stored valve%s: surface %.2f mm (SD %.2f over %d frames; open %.2f, "
          "closed "
          "%.2f), papillary tips %.2f mm\n",
          p.synthetic ? " (the virtual truth)" : "", s["error_mean_mm"].get<double>(),
          s["error_sd_mm"].get<double>(), s["frames"].get<int>(),
          s["by_phase"]
              .value("open", nlohmann::json::object())
              .value("error_mean_mm", std::nan("")),
          s["by_phase"]
              .value("closed", nlohmann::json::object())
              .value("error_mean_mm", std::nan("")),
          s["papillary_error_mm"].get<double>());
      report["against_stored"] = s;
      report["per_frame"] = run["frames"];
    }
  }
  if (!a.json_path.empty()) {
    write_json_file(a.json_path, report);
    std::cout << "wrote " << a.json_path << "\n";
  }
  std::cout << "wrote /detected into " << dest.string() << "\n";
  return kExitOk;
}

void register_detect(CLI::App& app, Context& ctx) {
  {
    auto* cmd =
        app.add_subcommand("train-detector", "Train the valve detector on a cohort with images");
    cmd->footer(
        "Examples:\n"
        "  mvtwin train-detector --virtual 3 --voxel 2.5 --trees 8 --samples 300 --truth-set "
        "ures=16 --truth-set vres=8 --axial-psf 0.5 --lateral-psf 2.2 --out detector.yml.gz   # a "
        "small one, to try\n"
        "  mvtwin train-detector --virtual 12 --out detector12.yml.gz --cache truths/   # long\n"
        "(or --cohort DIR: patient files with images, e.g. made by mvtwin render-tee)\n"
        "--cohort: every patient file in the directory with images (mvtwin render-tee) and a\n"
        "valve in the same frames is used: each frame with landmarks and an LA surface is one\n"
        "training volume. --virtual N: N virtual patients (synthetic; seeds --cohort-seed x 1000 "
        "+\n"
        "1..N, pathologies in turn), their closing frames simulated and every frame rendered as\n"
        "synthetic TEE (--voxel, --axial-psf, --lateral-psf, --probe-jitter), --jobs at once.");
    auto a = std::make_shared<TrainDetectorArgs>();
    a->render.probe_jitter_deg = 10;  // a detector trained for any patient's view
    auto* cohort_opt =
        cmd->add_option("--cohort", a->cohort, "directory of patient files (HDF5) with images");
    cmd->add_option("--virtual", a->n_virtual,
                    "train on this many virtual patients instead (synthetic)")
        ->check(CLI::Range(3, 499))
        ->excludes(cohort_opt);
    cmd->add_option("--cohort-seed", a->cohort_seed, "with --virtual: the cohort's seed")
        ->default_val(3030);
    cmd->add_option("--voxel", a->render.voxel_mm, "with --virtual: voxel size, mm")
        ->default_val(a->render.voxel_mm);
    cmd->add_option("--axial-psf", a->render.axial_psf_mm,
                    "with --virtual: point-spread SD along the beam, mm (coarser renders faster)")
        ->default_val(a->render.axial_psf_mm);
    cmd->add_option("--lateral-psf", a->render.lateral_psf_mm,
                    "with --virtual: point-spread SD across the beam at the probe depth, mm")
        ->default_val(a->render.lateral_psf_mm);
    cmd->add_option("--probe-jitter", a->render.probe_jitter_deg,
                    "with --virtual: probe pose variation, degrees")
        ->default_val(a->render.probe_jitter_deg);
    cmd->add_option("--jobs", a->jobs, "with --virtual: patients prepared at once")
        ->default_val(2)
        ->check(CLI::Range(1, 256));
    cmd->add_option("--cache", a->cache,
                    "with --virtual: directory keeping the simulated patients");
    cmd->add_option("--train-noise", a->train_noise,
                    "with --virtual: electronic noise SDs of the renders (patients cycle)")
        ->delimiter(',')
        ->default_str("0.004,0.016,0.063,0");
    cmd->add_option("--truth-set", a->truth_sets,
                    "with --virtual: name=value for the model simulating the closing frames");
    cmd->add_option("--out", a->out, "model file (.yml.gz)")->required();
    cmd->add_flag("--force", a->force, "replace an existing model file");
    cmd->add_option("--trees", a->detector.trees, "trees per forest")
        ->default_val(a->detector.trees);
    cmd->add_option("--samples", a->detector.samples_per_volume,
                    "training samples per volume and detector")
        ->default_val(a->detector.samples_per_volume);
    cmd->add_option("--seed", a->detector.seed, "random seed")->default_val(a->detector.seed);
    run_on_parse(cmd, ctx, a, run_train_detector);
  }
  {
    auto* cmd = app.add_subcommand("detect", "Detect the valve in a patient's images");
    cmd->footer(
        "Example:\n  mvtwin detect observed.h5 --model detector.yml.gz\n"
        "Detects landmarks, papillary tips and the LA surface in every frame (tracked) and writes\n"
        "them into the patient file as /detected, beside the stored sequence (never over it);\n"
        "--out writes a copy instead. Then: mvtwin simulate|calibrate|clip ... --use-detected.\n"
        "When the file holds a known valve in the same frames, the error is reported.");
    auto a = std::make_shared<DetectArgs>();
    cmd->add_option("FILE", a->file, "patient file (HDF5) with images")->required();
    cmd->add_option("--model", a->model, "detector model (mvtwin train-detector)")->required();
    cmd->add_option("--out", a->out,
                    "write the patient with its detection here instead of updating FILE");
    cmd->add_flag("--force", a->force, "replace an earlier detection, or an existing --out");
    cmd->add_option("--json", a->json_path,
                    "write the timing and, with a stored valve, the errors here");
    run_on_parse(cmd, ctx, a, run_detect);
  }
}

}  // namespace mvtwin::tools
