#include "output_files.h"

#include <cstdio>
#include <fstream>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/simulation_file.h"
#include "mvtwin/core/version.h"
#include "mvtwin/forward/closure_settings.h"
#include "report.h"

namespace mvtwin::tools {

void write_simulation_result(const std::filesystem::path& out, const forward::ClosureResult& r,
                             const forward::ClosureOptions& o, const ValveParameters& par,
                             const Patient& p, const std::string& patient_file,
                             const std::string& command_line) {
  SimulationRecord rec = forward::make_simulation_record(r, o, par);
  rec.patient_id = p.id;
  rec.patient_file = patient_file;
  rec.synthetic = p.synthetic;
  rec.provenance.version = kVersion;
  rec.provenance.command = command_line;
  rec.provenance.created_utc = utc_now_iso8601();
  rec.provenance.seed = p.provenance.seed;
  rec.provenance.source = assumed_note(p);
  write_simulation_file(out, rec);
}

std::filesystem::path summary_path(const std::filesystem::path& result_file) {
  if (result_file.extension() == ".json")
    throw Error("--out " + result_file.string() +
                ": the result is an HDF5 file (its JSON summary is written beside it with the "
                "extension .json)");
  return std::filesystem::path(result_file).replace_extension(".json");
}

nlohmann::json simulation_summary_json(const forward::ClosureResult& r,
                                       const forward::ClosureOptions& o, const ValveParameters& par,
                                       const Patient& p, const std::string& command_line) {
  nlohmann::json parameters, options;
  par.for_each([&](const std::string& n, double v, const char*) { parameters[n] = v; });
  for (const auto& [k, v] : forward::describe_result_options(o)) options[k] = v;
  nlohmann::json j = {{"patient_id", p.id},
                      {"synthetic", p.synthetic},
                      {"mvtwin_version", kVersion},
                      {"command", command_line},
                      {"created_utc", utc_now_iso8601()},
                      {"seed", p.provenance.seed},
                      {"status", r.summary.converged() ? "converged" : "failed"},
                      {"outcome", std::string(outcome_name(r.summary.outcome))},
                      {"reason", r.summary.reason},
                      {"wall_s", r.summary.wall_s},
                      {"steps", r.summary.steps},
                      {"parameters", parameters},
                      {"options", options}};
  if (r.orifice) {
    j.update(orifice_json(*r.orifice));
  } else {
    for (const char* k : {"aroa_mm2", "eroa_mm2", "openings_mm2", "mr_grade",
                          "coaptation_length_mm", "coaptation_depth_mm"})
      j[k] = nullptr;
  }
  if (!r.clip_gap_end_mm.empty()) j["clip_gap_end_mm"] = r.clip_gap_end_mm;
  if (o.static_rest) {
    const forward::ClosureSummary& s = r.summary;
    j["static_solve"] = {
        {"converged", s.static_failure.empty()},  {"iterations", s.static_iterations},
        {"residual_n", s.static_residual_n},      {"relative_residual", s.static_relative_residual},
        {"residual_history_n", s.static_history}, {"failure", s.static_failure}};
  }
  return j;
}

std::string assumed_note(const Patient& p) {
  const std::string a = p.sequence.assumed_landmarks();
  return a.empty() ? "" : "input ASSUMED (estimated from published anatomy, not observed): " + a;
}

void write_json_file(const std::filesystem::path& path, const nlohmann::json& j, int indent) {
  if (path.empty()) return;
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream f(tmp);
    f << j.dump(indent) << "\n";
    if (!f) throw Error(path.string() + ": cannot write");
  });
}

}  // namespace mvtwin::tools
