// mvtwin bench closure | solvers: timing figures, not tests. Each prints a table and, with
// --json FILE, writes the figures with what produced them (version, command, settings). The
// experiments are studies: `mvtwin study convergence`, `robustness`, `detection` and the
// calibration stage of `mvtwin study cohort` replaced bench accuracy, stability, detect and
// calibrate.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench.h"
#include "bench_import.h"
#include "exit_codes.h"
#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/point_to_mesh_distance.h"
#include "mvtwin/core/simulation_file.h"
#include "mvtwin/core/units.h"
#include "mvtwin/core/version.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/forward/closure_simulation.h"
#include "output_files.h"
#include "progress.h"

namespace mvtwin::tools {
namespace {

using nlohmann::json;

void write_json(const std::string& path, const json& j) {
  if (path.empty()) return;
  write_json_file(path, j);
  std::cout << "wrote " << path << "\n";
}

struct Run {
  forward::ClosureResult result;
  double wall_s = 0;
};

Run run(const Patient& p, forward::ClosureOptions o) {
  Run r;
  r.result = forward::simulate_closure(p.sequence, p.truth->parameters, o);
  r.wall_s = r.result.summary.wall_s;
  return r;
}

json summary_json(const Run& r) {
  const auto& s = r.result.summary;
  return {{"status", s.converged() ? "converged" : "failed"},
          {"reason", s.reason},
          {"wall_s", s.wall_s},
          {"steps", s.steps},
          {"halvings", s.halvings},
          {"rejected_steps", s.rejected},
          {"dofs", s.dofs},
          {"tets", s.elements},
          {"assembly_s", s.assembly_s},
          {"solve_s", s.solve_s},
          {"contact_s", s.contact_s},
          {"factorizations", s.factorizations},
          {"min_contact_distance_mm", s.min_contact_distance_mm},
          {"orifice_end_mm2", r.result.samples.back().orifice_area_mm2}};
}

std::string join(const std::vector<std::string>& v) {
  std::string out;
  for (const auto& s : v) out += (out.empty() ? "" : " ") + s;
  return out;
}

forward::ClosureOptions with_settings(forward::ClosureOptions o,
                                      const std::vector<std::string>& sets) {
  for (const auto& a : sets)
    forward::apply_option(a, &o, "bench simulates virtual patients with their hidden parameters");
  std::string err;
  if (!o.is_valid(&err)) throw Error("bench: " + err);
  return o;
}

/// The reference run's end surface: read from `file` when it holds a run of the same patient
/// with the same options, else simulated (and written to `file` if one is named).
LeafletGrid reference_surface(const Patient& p, const forward::ClosureOptions& ro,
                              const std::string& file, const std::string& command_line) {
  // What decides the result: every option but how often states are recorded and how the
  // linear solver spends its work to reach its tolerance, and what cannot change a result. A file
  // made before error-controlled steps had fixed ones (step_error_mm = 0, which makes max_dt
  // irrelevant).
  auto physics = [](const std::vector<std::pair<std::string, std::string>>& o) {
    const auto r = forward::result_options(o);
    std::map<std::string, std::string> m(r.begin(), r.end());
    for (const char* k :
         {"record_every", "refactor_iterations", "pcg_max_iterations", "rotated_preconditioner",
          "single_precision_preconditioner", "single_precision_factorization", "warm_start"})
      m.erase(k);
    if (!m.count("step_error_mm")) m["step_error_mm"] = "0";
    if (m["step_error_mm"] == "0") m.erase("max_dt");
    return m;
  };
  const auto wanted = physics(forward::describe_options(ro));
  if (!file.empty() && std::filesystem::exists(file)) {
    const SimulationRecord rec = read_simulation_file(file);
    if (rec.patient_id == p.id && physics(rec.options) == wanted && rec.status == "converged" &&
        !rec.la_surface.empty()) {
      std::cout << "reference: " << file << " (reused; made by mvtwin " << rec.provenance.version
                << " on " << rec.provenance.created_utc << ")\n";
      if (rec.provenance.version != kVersion)
        std::cout << "  note: another mvtwin version made it; delete the file to recompute\n";
      return rec.la_surface.back();
    }
    std::cout << "reference: " << file << " has other settings or another patient; recomputing\n";
  }
  std::cout << "reference run (" << ro.model.ures << " x " << ro.model.vres << ", dt " << ro.dt
            << " s; the default reference takes about an hour on this kind of machine, --ref-file "
               "keeps it) ..."
            << std::endl;
  forward::ClosureOptions o = ro;
  o.progress = progress_line("  reference");
  const forward::ClosureResult r = forward::simulate_closure(p.sequence, p.truth->parameters, o);
  std::cout << r.summary.brief_report() << "\n";
  if (!r.summary.converged()) throw Error("bench: the reference run failed: " + r.summary.reason);
  if (!file.empty()) {
    SimulationRecord rec = forward::make_simulation_record(r, ro, p.truth->parameters);
    rec.patient_id = p.id;
    rec.synthetic = true;
    rec.provenance.version = kVersion;
    rec.provenance.command = command_line;
    rec.provenance.created_utc = utc_now_iso8601();
    rec.provenance.seed = p.provenance.seed;
    write_simulation_file(file, rec);
    std::cout << "wrote the reference to " << file << "\n";
  }
  return r.samples.back().la_surface;
}

/// The reference run's settings: kReferenceSettings, then the user's --ref-set on top (a
/// reference keeps fixed steps unless --ref-set says otherwise).
std::vector<std::string> reference_settings(const std::vector<std::string>& ref_sets) {
  std::vector<std::string> all = kReferenceSettings;
  all.insert(all.end(), ref_sets.begin(), ref_sets.end());
  return all;
}

}  // namespace

namespace {

/// The paired run's settings: --pair-set, kPairSettings when none is given, none with --no-pair.
std::vector<std::string> pair_settings(const std::string& command, bool no_pair,
                                       const std::vector<std::string>& given) {
  if (no_pair && !given.empty())
    throw Error(command + ": --no-pair and --pair-set contradict each other");
  if (no_pair) return {};
  return given.empty() ? kPairSettings : given;
}

/// The reference file of one patient: `pattern` with {seed} replaced by the seed.
std::string reference_file_for(const std::string& pattern, std::uint64_t seed) {
  std::string out = pattern;
  const size_t at = out.find("{seed}");
  if (at != std::string::npos) out.replace(at, 6, std::to_string(seed));
  return out;
}

json distance_json(const DistanceStats& e, const std::string& prefix) {
  return {{prefix + "_mean_mm", e.mean},
          {prefix + "_sd_mm", e.sd},
          {prefix + "_p95_mm", e.p95},
          {prefix + "_max_mm", e.max}};
}

}  // namespace

int run_bench_closure(const BenchClosureArgs& a) {
  if (a.repeat < 1) throw Error("bench closure: --repeat must be >= 1");
  if (a.seeds.empty()) throw Error("bench closure: --seeds names no patient");
  if (a.reference && a.seeds.size() > 1 && !a.ref_file.empty() &&
      a.ref_file.find("{seed}") == std::string::npos)
    throw Error("bench closure: --ref-file must contain {seed} for more than one patient (" +
                a.ref_file + ")");
  // The variants, timed alternately: the given settings, then (paired) the same with
  // --pair-set on top, so that both see the same machine.
  struct Variant {
    std::string name;
    std::vector<std::string> added;
    forward::ClosureOptions options;
  };
  const std::vector<std::string> pair_sets = pair_settings("bench closure", a.no_pair, a.pair_sets);
  std::vector<Variant> variants = {{"timed", {}, with_settings({}, a.sets)}};
  if (!pair_sets.empty()) {
    std::vector<std::string> all = a.sets;
    all.insert(all.end(), pair_sets.begin(), pair_sets.end());
    variants.push_back({"paired", pair_sets, with_settings({}, all)});
  }
  const std::vector<std::string> ref_sets = reference_settings(a.ref_sets);
  const forward::ClosureOptions ro = with_settings({}, ref_sets);
  // The own rest: the timed settings settled (static_rest off) to 0.001 mm per step.
  std::vector<std::string> rest_sets = a.sets;
  rest_sets.push_back("static_rest=off");
  rest_sets.insert(rest_sets.end(), kRestSettings.begin(), kRestSettings.end());
  const forward::ClosureOptions rest_options = with_settings({}, rest_sets);

  json rows = json::array();
  for (const std::uint64_t seed : a.seeds) {
    const Patient p = make_virtual_patient(seed);
    std::vector<std::vector<double>> walls(variants.size());
    std::vector<Run> best(variants.size());
    for (int k = 0; k < a.repeat; ++k) {
      for (size_t v = 0; v < variants.size(); ++v) {
        std::cout << "patient " << seed << ", " << variants[v].name << " run " << k + 1 << "/"
                  << a.repeat << " ..." << std::endl;
        Run r = run(p, variants[v].options);
        walls[v].push_back(r.wall_s);
        if (k == 0 || r.wall_s < best[v].wall_s) best[v] = std::move(r);
      }
    }
    std::optional<LeafletGrid> ref_surface;
    if (a.reference)
      ref_surface = reference_surface(p, ro, reference_file_for(a.ref_file, seed), a.command_line);
    std::optional<Run> rest;
    if (a.rest) {
      std::cout << "patient " << seed << ", at-rest run (" << join(kRestSettings) << ") ..."
                << std::endl;
      rest = run(p, rest_options);
      if (!rest->result.summary.converged())
        std::cout << "at-rest run failed: " << rest->result.summary.reason << "\n";
    }
    for (size_t v = 0; v < variants.size(); ++v) {
      const Run& b = best[v];
      const auto& s = b.result.summary;
      std::vector<double> sorted = walls[v];
      std::sort(sorted.begin(), sorted.end());
      json j = summary_json(b);
      j["patient_seed"] = seed;
      j["variant"] = variants[v].name;
      j["added_settings"] = variants[v].added;
      j["wall_s"] = sorted.front();
      j["wall_s_median"] = sorted[sorted.size() / 2];
      j["wall_s_all"] = walls[v];
      j["settle_steps"] = s.settle_steps;
      j["settle_s"] = s.settle_s;
      j["settle_newton_iterations"] = s.settle_newton_iterations;
      j["newton_iterations"] = s.newton_iterations;
      j["last_step_motion_mm"] = s.last_step_motion_mm;
      if (variants[v].options.static_rest) {
        j["static_iterations"] = s.static_iterations;
        j["static_converged"] = s.static_failure.empty();
        j["static_residual_n"] = s.static_residual_n;
        j["static_relative_residual"] = s.static_relative_residual;
        j["static_history_n"] = s.static_history;
        if (!s.static_failure.empty()) j["static_failure"] = s.static_failure;
      }
      const LeafletGrid& end = b.result.samples.back().la_surface;
      std::string error_text = "-", lag_text = "-";
      char buf[96];
      if (ref_surface) {
        const DistanceStats e =
            symmetric_surface_distance(end.triangulate(), ref_surface->triangulate()).symmetric;
        j.update(distance_json(e, "error"));
        std::snprintf(buf, sizeof buf, "%.3f / %.3f", e.mean, e.max);
        error_text = buf;
      }
      if (rest && rest->result.summary.converged()) {
        const auto& rs = rest->result.summary;
        const DistanceStats lag =
            symmetric_surface_distance(end.triangulate(),
                                       rest->result.samples.back().la_surface.triangulate())
                .symmetric;
        j.update(distance_json(lag, "rest_lag"));
        j["rest_status"] = "converged";
        j["rest_settle_steps"] = rs.settle_steps;
        j["rest_settle_s"] = rs.settle_s;
        j["rest_last_step_motion_mm"] = rs.last_step_motion_mm;
        std::snprintf(buf, sizeof buf, "%.3f / %.3f", lag.mean, lag.max);
        lag_text = buf;
      } else if (rest) {
        j["rest_status"] = "failed";
      }
      std::printf(
          "patient %-3llu %-7s wall_s %6.2f (median %6.2f)  steps %4d  settle %3d x%-2d newton "
          "%3d  error vs reference %s mm  lag behind own rest %s mm%s\n",
          static_cast<unsigned long long>(seed), variants[v].name.c_str(), sorted.front(),
          sorted[sorted.size() / 2], s.steps, s.settle_steps, s.settle_newton_iterations,
          s.static_iterations, error_text.c_str(), lag_text.c_str(),
          s.converged() ? (s.static_failure.empty() ? "" : "  (static solve failed, settled)")
                        : ("  FAILED: " + s.reason).c_str());
      std::fflush(stdout);
      rows.push_back(j);
    }
    if (rest && rest->result.summary.converged())
      std::cout << "  own rest: " << rest->result.summary.settle_steps << " settling steps, "
                << rest->result.summary.settle_s << " s, last step "
                << rest->result.summary.last_step_motion_mm << " mm\n";
  }
  json j{{"runs", rows},
         {"seeds", a.seeds},
         {"synthetic", true},
         {"settings", forward::describe_options(variants[0].options)},
         {"pair_settings", pair_sets},
         {"rest_settings", rest_sets},
         {"provenance", provenance(a.command_line)}};
  if (a.reference) j["reference_settings"] = ref_sets;
  write_json(a.json_path, j);
  return kExitOk;
}

int run_bench_solvers(const BenchSolversArgs& a) {
  for (const double t : a.tolerances) {
    if (!(t > 0 && t < 1)) {
      char given[32];
      std::snprintf(given, sizeof given, "%g", t);
      throw Error(std::string("bench solvers: --tolerances must be in (0, 1), not ") + given);
    }
  }
  const Patient p = make_virtual_patient(a.seed);
  const std::vector<std::string> ref_sets = reference_settings(a.ref_sets);
  const LeafletGrid ref =
      reference_surface(p, with_settings({}, ref_sets), a.ref_file, a.command_line);
  const std::vector<std::vector<std::string>> variants = {
      {"solver=cholmod-supernodal"},
      {"solver=cholmod-simplicial"},
      {"solver=eigen-ldlt"},
      {"solver=reused-factor-pcg", "rotated_preconditioner=on"},
      {"solver=reused-factor-pcg", "rotated_preconditioner=off"}};
  const std::vector<std::string> pair_sets = pair_settings("bench solvers", a.no_pair, a.pair_sets);
  // Each solver's run, then (paired, one after the other) the same with pair_sets on top.
  std::vector<std::vector<std::string>> pairs = {{}};
  if (!pair_sets.empty()) pairs.push_back(pair_sets);
  json rows = json::array();
  std::cout << "solver                       tol    rest     wall_s  solve_s  factorizations  "
               "pcg_iterations  error_mean_mm  error_max_mm\n";
  for (const double t : a.tolerances) {
    char tol[32];
    std::snprintf(tol, sizeof tol, "%g", t);
    for (const auto& v : variants)
      for (const auto& added : pairs) {
        std::vector<std::string> all = a.sets;
        all.insert(all.end(), v.begin(), v.end());
        all.push_back(std::string("pcg_tolerance=") + tol);
        all.insert(all.end(), added.begin(), added.end());
        const forward::ClosureOptions o = with_settings({}, all);
        const Run r = run(p, o);
        const auto& s = r.result.summary;
        const DistanceStats e =
            symmetric_surface_distance(r.result.samples.back().la_surface.triangulate(),
                                       ref.triangulate())
                .symmetric;
        json row = summary_json(r);
        row["variant"] = v;
        row["added_settings"] = added;
        row["static_rest"] = o.static_rest;
        if (o.static_rest) {
          row["static_iterations"] = s.static_iterations;
          row["static_converged"] = s.static_failure.empty();
        }
        row["settle_steps"] = s.settle_steps;
        row["pcg_tolerance"] = t;
        row["pcg_iterations"] = s.pcg_iterations;
        row["factorize_s"] = s.factorize_s;
        row["error_mean_mm"] = e.mean;
        row["error_max_mm"] = e.max;
        rows.push_back(row);
        std::string name = v[0].substr(7);
        if (v.size() > 1) name += v[1] == "rotated_preconditioner=on" ? " (rotated)" : " (plain)";
        char line[240];
        const char* rest = !o.static_rest             ? "settle"
                           : s.static_failure.empty() ? "static"
                                                      : "static*";
        std::snprintf(line, sizeof line, "%-28s %-6s %-7s %7.2f %8.2f %15d %15d %14.3f %13.3f%s\n",
                      name.c_str(), tol, rest, s.wall_s, s.solve_s, s.factorizations,
                      s.pcg_iterations, e.mean, e.max,
                      s.converged() ? "" : ("  FAILED: " + s.reason).c_str());
        std::cout << line << std::flush;
      }
  }
  json j{{"runs", rows},
         {"patient_seed", a.seed},
         {"synthetic", true},
         {"reference_settings", ref_sets},
         {"pair_settings", pair_sets},
         {"provenance", provenance(a.command_line)}};
  write_json(a.json_path, j);
  return kExitOk;
}

void register_bench(CLI::App& app, Context& ctx) {
  auto* bench = app.add_subcommand("bench", "Benchmarks: time and the error it costs");
  register_bench_import(*bench, ctx);
  bench->require_subcommand(1);

  // ---- bench closure ----------------------------------------------------------------------
  {
    auto* cmd = bench->add_subcommand(
        "closure",
        "Closures of virtual patients, timed, paired with the static solve, against references");
    cmd->footer(
        "Examples:\n"
        "  mvtwin bench closure --set ures=16 --set vres=8 --ref-set ures=20 --ref-set vres=10 "
        "--ref-set dt=0.005 --ref-set settle_mm=0.01 --repeat 1 --json closure_small.json "
        "--ref-file ref_small.h5\n"
        "  mvtwin bench closure --json closure.json --ref-file closure_ref.h5   # long: the "
        "reference, once\n"
        "  mvtwin bench closure --seeds 1,2,3,4,5 --no-reference --set threads=1 --json "
        "closure_1to5.json   # long: five patients, the lag behind rest only\n"
        "The timed run uses the paper's settings (ures = vres = 30, dt = 0.01 s) unless --set\n"
        "says otherwise and is repeated (--repeat; wall_s is the fastest, all are listed). Each\n"
        "timed run is paired with the same settings plus --pair-set (by default static_rest=on:\n"
        "the closed valve at rest by the static solve beside settling), the two run alternately\n"
        "so that both see the same machine (--no-pair: the timed run alone). The reference is a\n"
        "finer, smaller-step run (--ref-set), settled at peak pressure until no step moves it\n"
        "0.001 mm: error_mean_mm / error_max_mm are the symmetric point-to-mesh distances\n"
        "between the end surfaces. --ref-file keeps it as a simulation file and reuses it when\n"
        "its settings match ({seed} in the name for several patients); --no-reference skips it\n"
        "(it takes about an hour). rest_lag_mean_mm / rest_lag_max_mm: each run's end against\n"
        "the timed settings settled to 0.001 mm per step (the grid's own rest; --no-rest skips\n"
        "it). Patients: --seeds, the virtual patients of `mvtwin phantom --seed`.");
    auto a = std::make_shared<BenchClosureArgs>();
    cmd->add_option("--json", a->json_path, "write the figures here");
    cmd->add_option("--set", a->sets, "name=value for the timed run (repeatable)");
    cmd->add_option("--pair-set", a->pair_sets,
                    "name=value added for the paired run (repeatable; replaces the default)")
        ->default_str(join(kPairSettings));
    cmd->add_flag("--no-pair", a->no_pair, "no paired run");
    cmd->add_option("--ref-set", a->ref_sets,
                    "name=value for the reference run, over its defaults (repeatable)")
        ->default_str(join(kReferenceSettings));
    cmd->add_option("--ref-file", a->ref_file,
                    "reference simulation file to reuse or write ({seed}: the patient's seed)");
    cmd->add_flag("!--no-reference", a->reference, "no reference run (no error_* figures)");
    cmd->add_option("--seed,--seeds", a->seeds, "virtual patients (comma-separated seeds)")
        ->delimiter(',')
        ->default_str("1");
    cmd->add_option("--repeat", a->repeat, "timed runs (the fastest is reported)")->default_val(3);
    cmd->add_flag("!--no-rest", a->rest,
                  "skip the at-rest run (the timed settings settled to 0.001 mm per step, to "
                  "measure each run's lag behind rest)");
    run_on_parse(cmd, ctx, a, run_bench_closure);
  }

  // ---- bench solvers -----------------------------------------------------------------------
  {
    auto* cmd = bench->add_subcommand("solvers",
                                      "Linear solvers at equal accuracy: time and error of each");
    cmd->footer(
        "Examples:\n"
        "  mvtwin bench solvers --set ures=16 --set vres=8 --ref-set ures=20 --ref-set vres=10 "
        "--ref-set dt=0.005 --ref-set settle_mm=0.01 --tolerances 0.1 --no-pair --json "
        "solvers_small.json --ref-file ref_small.h5   # the reference above, reused\n"
        "  mvtwin bench solvers --json solvers.json --ref-file closure_ref.h5   # long\n"
        "The default patient's closure at the paper's settings with each linear solver: a\n"
        "factorization every step (CHOLMOD supernodal, CHOLMOD simplicial, Eigen LDLT) and the\n"
        "reused factorization as a preconditioner (with and without the rotation of the\n"
        "factor), each at every --tolerances (linear); error against the reference run. Each\n"
        "is paired with the same settings plus --pair-set (default static_rest=on: the closed\n"
        "valve at rest by the static solve; column rest: settle, static, or static* where the\n"
        "static solve failed and settling finished); --no-pair: settling only.");
    auto a = std::make_shared<BenchSolversArgs>();
    cmd->add_option("--json", a->json_path, "write the figures here");
    cmd->add_option("--set", a->sets, "name=value for every run (repeatable)");
    cmd->add_option("--ref-set", a->ref_sets,
                    "name=value for the reference run, over its defaults (repeatable)")
        ->default_str(join(kReferenceSettings));
    cmd->add_option("--ref-file", a->ref_file, "reference simulation file to reuse or write");
    cmd->add_option("--tolerances", a->tolerances,
                    "linear-solve tolerances (relative residual), each run with every solver")
        ->delimiter(',')
        ->default_str("0.1,0.001");
    cmd->add_option("--pair-set", a->pair_sets,
                    "name=value added for each solver's paired run (repeatable; replaces the "
                    "default)")
        ->default_str(join(kPairSettings));
    cmd->add_flag("--no-pair", a->no_pair, "no paired runs");
    cmd->add_option("--seed", a->seed, "virtual patient")->default_val(1);
    run_on_parse(cmd, ctx, a, run_bench_solvers);
  }
}

}  // namespace mvtwin::tools
