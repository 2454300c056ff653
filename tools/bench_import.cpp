// mvtwin bench import: virtual patients turned into label maps and imported back.
#include <chrono>
#include <cmath>
#include <iostream>

#include <nlohmann/json.hpp>

#include "bench_import.h"
#include "exit_codes.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/point_to_mesh_distance.h"
#include "mvtwin/core/version.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/detection/label_map.h"
#include "mvtwin/detection/patient_import.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/forward/virtual_closure.h"
#include "output_files.h"

namespace mvtwin::tools {
namespace {

using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// Mean distance from fitted annulus points to the true annulus curve, mm.
double curve_error(const Points& fitted, const Points& truth) {
  const Points dense = resample_closed_curve(truth, 2000);
  double s = 0;
  for (Eigen::Index u = 0; u < fitted.rows(); ++u)
    s += std::sqrt((dense.rowwise() - fitted.row(u)).rowwise().squaredNorm().minCoeff());
  return s / static_cast<double>(fitted.rows());
}

}  // namespace

int run_bench_import(const BenchImportArgs& a) {
  forward::VirtualClosureOptions vo;
  vo.simulation = forward::ClosureOptions{};
  for (const auto& s : a.closure_sets) {
    // Options only: the virtual patients' hidden parameters are what is simulated.
    forward::apply_option(s, &vo.simulation,
                          "--closure-set: the virtual patients' hidden ones are simulated");
  }
  vo.noise_mm = 0.0;
  std::vector<Patient> patients;
  for (int i = 0; i < a.n; ++i) {
    Patient p = make_cohort_patient(a.seed, i);
    forward::simulate_observed_closure(&p, vo);
    std::cout << "patient " << i + 1 << "/" << a.n << ": " << p.id << " [SYNTHETIC] simulated\n"
              << std::flush;
    patients.push_back(std::move(p));
  }
  nlohmann::json rows = nlohmann::json::array(), per_patient = nlohmann::json::array();
  for (double voxel : a.voxels) {
    for (const std::string conv : {"mvtool", "mvseg"}) {
      double open = 0, closed = 0, ann = 0, pap = 0, secs = 0;
      int frames = 0, failed = 0;
      for (const Patient& p : patients) {
        const ValveSequence& s = p.sequence;
        detection::LabelMapOptions lo;
        lo.labels = detection::segmentation_labels(conv);
        lo.voxel_mm = voxel;
        lo.boundary_noise = a.noise;
        std::vector<detection::LabelFrame> lf;
        for (int f : {s.end_diastole, s.first_closed}) {
          lo.seed = p.provenance.seed * 7 + static_cast<std::uint64_t>(f);
          lf.push_back({detection::valve_label_map(s.frames[f], lo), s.frames[f].time_s,
                        p.id + "/" + std::to_string(f), std::nullopt, std::nullopt});
        }
        detection::PatientImportOptions io;
        io.fit.labels = lo.labels;
        io.fit.ures = s.ures;
        io.fit.vres = s.vres;
        try {
          const auto t0 = std::chrono::steady_clock::now();
          const detection::PatientImport r = detection::import_patient(lf, {}, io);
          secs += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          frames += 2;
          const ValveSequence& q = r.patient.sequence;
          const double e_open =
              symmetric_surface_distance(q.frames[0].la_surface->triangulate(),
                                         s.frames[s.end_diastole].la_surface->triangulate())
                  .symmetric.mean;
          const double e_closed =
              symmetric_surface_distance(q.frames[1].la_surface->triangulate(),
                                         s.frames[s.first_closed].la_surface->triangulate())
                  .symmetric.mean;
          const double e_ann =
              0.5 * (curve_error(q.frames[0].annulus, s.frames[s.end_diastole].annulus) +
                     curve_error(q.frames[1].annulus, s.frames[s.first_closed].annulus));
          double e_pap = 0;
          for (Landmark l :
               {Landmark::kAnterolateralPapillaryTip, Landmark::kPosteromedialPapillaryTip})
            e_pap += 0.5 * (q.frames[0].landmark(l) - s.frames[s.end_diastole].landmark(l)).norm();
          open += e_open;
          closed += e_closed;
          ann += e_ann;
          pap += e_pap;
          per_patient.push_back({{"patient", p.id},
                                 {"pathology", pathology_name(p.truth->pathology)},
                                 {"voxel_mm", voxel},
                                 {"convention", conv},
                                 {"surface_error_open_mm", e_open},
                                 {"surface_error_closed_mm", e_closed},
                                 {"annulus_error_mm", e_ann},
                                 {"papillary_error_mm", e_pap}});
        } catch (const Error& e) {
          ++failed;
          per_patient.push_back(
              {{"patient", p.id}, {"voxel_mm", voxel}, {"convention", conv}, {"failed", e.what()}});
          std::cout << "  " << p.id << " " << conv << " " << voxel << " mm: FAILED: " << e.what()
                    << "\n";
        }
      }
      const int ok = static_cast<int>(patients.size()) - failed;
      const double k = ok > 0 ? 1.0 / ok : std::nan("");
      nlohmann::json row = {{"voxel_mm", voxel},
                            {"convention", conv},
                            {"patients", ok},
                            {"failed", failed},
                            {"surface_error_open_mm", open * k},
                            {"surface_error_closed_mm", closed * k},
                            {"annulus_error_mm", ann * k},
                            {"papillary_error_mm", pap * k},
                            {"papillary", "estimated from anatomy (not given)"},
                            {"s_per_frame", frames > 0 ? secs / frames : std::nan("")}};
      rows.push_back(row);
      std::printf(
          "voxel %.1f mm %-7s: surface open %.3f mm, closed %.3f mm, annulus %.3f mm, "
          "papillary (estimated) %.1f mm, "
          "%.2f s/frame, %d failed\n",
          voxel, conv.c_str(), open * k, closed * k, ann * k, pap * k,
          frames > 0 ? secs / frames : 0.0, failed);
    }
  }
  nlohmann::json j = {
      {"benchmark", "import"},           {"synthetic", "virtual patients: SYNTHETIC"},
      {"cohort_seed", a.seed},           {"boundary_noise", a.noise},
      {"closure_model", a.closure_sets}, {"rows", rows},
      {"per_patient", per_patient}};
  j.update(provenance(a.command_line));
  if (!a.json_path.empty()) write_json_file(a.json_path, j);
  return kExitOk;
}

void register_bench_import(CLI::App& bench, Context& ctx) {
  auto* cmd =
      bench.add_subcommand("import", "Segmentation import on label maps of virtual patients");
  cmd->footer(
      "Examples:\n"
      "  mvtwin bench import --patients 1 --voxels 0.8 --closure-set ures=16 --closure-set vres=10 "
      "--json import1.json\n"
      "  mvtwin bench import --patients 10 --json import.json   # long\n"
      "Virtual patients (synthetic; seeds --seed x 1000 + 1..N), their closing frames simulated "
      "without noise by\n"
      "a small model (--closure-set), turned into label maps (end-diastole and first closed frame) "
      "at each voxel\n"
      "size and convention with partial-volume boundary noise, and imported back with their "
      "papillary tips\n"
      "estimated (not given). Per row (voxel size, convention): symmetric surface error against "
      "the virtual\n"
      "surfaces (open and closed frames), annulus error, papillary tip error of the estimate, s "
      "per frame (one core).");
  auto a = std::make_shared<BenchImportArgs>();
  cmd->add_option("--patients", a->n, "virtual patients")
      ->default_val(10)
      ->check(CLI::Range(1, 500));
  cmd->add_option("--seed", a->seed, "cohort seed")->default_val(4040);
  cmd->add_option("--voxels", a->voxels, "voxel sizes, mm")->delimiter(',')->default_str("0.5,0.8");
  cmd->add_option("--boundary-noise", a->noise, "partial-volume noise SD")->default_val(0.15);
  cmd->add_option("--closure-set", a->closure_sets,
                  "name=value for the model simulating the closed frames");
  cmd->add_option("--json", a->json_path, "write the figures as JSON");
  run_on_parse(cmd, ctx, a, run_bench_import);
}

}  // namespace mvtwin::tools
