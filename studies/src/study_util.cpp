#include "study_util.h"

#include <algorithm>
#include <cstdio>
#include <mutex>

#include "mvtwin/core/cache_key.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/version.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/forward/chordae_tuning.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/inverse/calibration.h"
#include "mvtwin/inverse/parameter_space.h"
#include "mvtwin/studies/report.h"
#include "mvtwin/studies/study_folder.h"

namespace mvtwin::studies::detail {

nlohmann::json describe(const forward::ClosureOptions& o) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [k, v] : forward::describe_options(o)) j[k] = v;
  return j;
}

nlohmann::json parameters_json(const ValveParameters& p) {
  nlohmann::json j = nlohmann::json::object();
  p.for_each([&](const std::string& name, double v, const char*) { j[name] = v; });
  return j;
}

void add_calibration_scans(nlohmann::json* config, const std::string& fit) {
  const inverse::ParameterSpace space(fit, ValveParameters{});
  for (const auto& spec : space.specs())
    if (spec.group == "modulus") {
      (*config)["modulus_scan"] = inverse::CalibrationOptions{}.modulus_scan;
      return;
    }
}

Stats stats(const std::vector<double>& v) {
  Stats s;
  double sum = 0, sq = 0;
  for (double x : v)
    if (std::isfinite(x)) {
      s.min = s.n ? std::min(s.min, x) : x;
      s.max = s.n ? std::max(s.max, x) : x;
      ++s.n;
      sum += x;
      sq += x * x;
    }
  if (s.n == 0) return s;
  s.mean = sum / s.n;
  s.sd = s.n > 1 ? std::sqrt(std::max(0.0, (sq - s.n * s.mean * s.mean) / (s.n - 1))) : 0.0;
  return s;
}

nlohmann::json stats_json(const std::vector<double>& v) {
  const Stats s = stats(v);
  using nlohmann::json;
  return {{"n", s.n},
          {"mean", s.n ? json(s.mean) : json(nullptr)},
          {"sd", s.n ? json(s.sd) : json(nullptr)},
          {"min", s.n ? json(s.min) : json(nullptr)},
          {"max", s.n ? json(s.max) : json(nullptr)}};
}

nlohmann::json nullable(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

double number_at(const nlohmann::json& j, const char* key) {
  return j.is_object() && j.contains(key) && j[key].is_number() ? j[key].get<double>() : kNaN;
}

std::string stats_text(const nlohmann::json& s, int digits) {
  if (!std::isfinite(number_at(s, "mean"))) return "n/a";
  return mean_sd(number_at(s, "mean"), number_at(s, "sd"), digits);
}

Patient study_patient(std::uint64_t seed, int index, const std::filesystem::path& file,
                      ValveParameters* parameters) {
  if (!file.empty()) {
    *parameters = ValveParameters{};
    return read_patient(file, false);
  }
  Patient p = make_cohort_patient(seed, index);
  *parameters = p.truth->parameters;
  return p;
}

std::filesystem::path observed_file(const std::filesystem::path& cache, const CohortMember& member,
                                    const forward::VirtualClosureOptions& observation) {
  std::string description = "patients=" + std::to_string(kVirtualPatientEdition) +
                            " noise=" + std::to_string(observation.noise_mm);
  // Only the normal valves change when tuned: the others keep the files made before.
  if (observation.tune_normal_chordae && member.pathology == Pathology::kNormal)
    description += " chordae_tuning=" + std::to_string(forward::kChordaeTuningEdition);
  for (const auto& [k, v] : forward::describe_result_options(observation.simulation))
    description += " " + k + "=" + v;
  return cache / ("observed_" + member.id + "_" + cache_key(description) + ".h5");
}

double ensure_observed(const std::filesystem::path& file, std::uint64_t seed, int index,
                       const forward::VirtualClosureOptions& observation) {
  {
    std::lock_guard<std::mutex> lock(hdf5_mutex());
    if (std::filesystem::exists(file)) {
      try {
        const Patient p = read_patient(file, false);
        if (p.sequence.has_closed_leaflets()) return 0.0;
      } catch (const Error&) {
        // damaged: make it again
      }
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  Patient p = make_cohort_patient(seed, index);
  forward::simulate_observed_closure(&p, observation);
  const double s = seconds_since(t0);
  std::lock_guard<std::mutex> lock(hdf5_mutex());
  write_patient(file, p);
  return s;
}

nlohmann::json provenance(const std::string& command, const std::string& workers, double wall_s) {
  return {{"mvtwin_version", kVersion},
          {"command", command},
          {"created_utc", utc_now_iso8601()},
          {"workers", workers},
          {"wall_s", wall_s}};
}

}  // namespace mvtwin::studies::detail
