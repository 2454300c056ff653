#include "result_header.h"

#include "mvtwin/core/version.h"

namespace mvtwin::h5 {

void write_result_header(const Location& root, const char* format, long format_version,
                         const char* kind, const ResultHeader& h) {
  root.attr("format", std::string(format));
  root.attr("format_version", format_version);
  root.attr("patient_id", h.patient_id);
  root.attr("patient_file", h.patient_file);
  root.attr("synthetic", static_cast<long>(h.synthetic));
  root.attr("data_origin", h.synthetic ? "SYNTHETIC: " + std::string(kind) + " of a virtual patient"
                                       : std::string(kind) + " of real or user-provided data");
  root.attr("mvtwin_version",
            h.provenance.version.empty() ? std::string(kVersion) : h.provenance.version);
  root.attr("command", h.provenance.command);
  root.attr("created_utc", h.provenance.created_utc);
  root.attr("seed", static_cast<long>(h.provenance.seed));
  // What the input assumed rather than observed (an imported patient's papillary tips, ...).
  if (!h.provenance.source.empty()) root.attr("source", h.provenance.source);
  std::vector<std::string> opts;
  for (const auto& [k, v] : h.options) opts.push_back(k + "=" + v);
  root.write_strings("options", opts);
}

ResultHeader read_result_header(const Location& root, const char* format, long format_version,
                                const char* kind) {
  if (!root.has_attr("format") || root.attr_string("format") != format) {
    root.fail("", std::string("not an mvtwin ") + kind + " file (root attribute format != '" +
                      format + "')");
  }
  if (root.attr_long("format_version") > format_version) {
    root.fail("", "format_version is newer than this mvtwin reads");
  }
  ResultHeader h;
  h.patient_id = root.attr_string("patient_id");
  h.patient_file = root.attr_string("patient_file");
  h.synthetic = root.attr_long("synthetic") != 0;
  h.provenance.version = root.attr_string("mvtwin_version");
  h.provenance.command = root.attr_string("command");
  h.provenance.created_utc = root.attr_string("created_utc");
  h.provenance.seed = static_cast<std::uint64_t>(root.attr_long("seed"));
  h.provenance.source = root.has_attr("source") ? root.attr_string("source") : "";
  for (const std::string& kv : root.read_strings("options")) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos) root.fail("options", "entry without '=': " + kv);
    h.options.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
  }
  return h;
}

}  // namespace mvtwin::h5
