#include "output_files.h"

#include <cstdio>
#include <fstream>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/simulation_file.h"
#include "mvtwin/core/version.h"

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
