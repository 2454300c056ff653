// mvtwin bench closure | accuracy | stability: figures, not tests. Each prints a table and,
// with --json FILE, writes the figures with what produced them (version, command, settings).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "output_files.h"
#include "progress.h"
#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/point_to_mesh_distance.h"
#include "mvtwin/core/units.h"
#include "mvtwin/core/rng.h"
#include "mvtwin/core/simulation_file.h"
#include "mvtwin/core/version.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/forward/closure_settings.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::tools {
namespace {

using nlohmann::json;

void write_json(const std::string& path, const json& j) {
  if (path.empty()) return;
  write_json_file(path, j);
  std::cout << "wrote " << path << "\n";
}

json provenance(const Context& ctx) {
  return {{"mvtwin_version", kVersion}, {"command", ctx.command_line},
          {"created_utc", utc_now_iso8601()}};
}

struct Run {
  forward::ClosureResult result;
  double wall_s = 0;
};

Run run(const Patient& p, forward::ClosureOptions o) {
  Run r;
  o.ruptured_marginal_chordae = p.truth->ruptured_marginal_chordae;
  r.result = forward::simulate_closure(p.sequence, p.truth->parameters, o);
  r.wall_s = r.result.summary.wall_s;
  return r;
}

/// Symmetric point-to-mesh distance between the end atrial surfaces of two runs.
DistanceStats end_error(const Run& a, const Run& ref) {
  return symmetric_surface_distance(a.result.samples.back().la_surface.triangulate(),
                                    ref.result.samples.back().la_surface.triangulate())
      .symmetric;
}

json summary_json(const Run& r) {
  const auto& s = r.result.summary;
  return {{"status", s.status == forward::ClosureStatus::kConverged ? "converged" : "failed"},
          {"reason", s.reason},
          {"wall_s", s.wall_s},
          {"steps", s.steps},
          {"halvings", s.halvings},
          {"dofs", s.dofs},
          {"tets", s.elements},
          {"assembly_s", s.assembly_s},
          {"solve_s", s.solve_s},
          {"contact_s", s.contact_s},
          {"factorizations", s.factorizations},
          {"min_contact_distance_mm", s.min_contact_distance_mm},
          {"orifice_end_mm2", r.result.samples.back().orifice_area_mm2}};
}

/// The converged reference of bench closure: a finer mesh, a 100x smaller step than the
/// paper's, linear systems solved to 1e-4 (the error against the reference does not move
/// between 0.1 and 1e-3 at the paper's step: docs/forward-status.md).
const std::vector<std::string> kReferenceSettings = {"ures=40", "vres=40", "dt=0.0001",
                                                     "pcg_tolerance=1e-4"};

std::string join(const std::vector<std::string>& v) {
  std::string out;
  for (const auto& s : v) out += (out.empty() ? "" : " ") + s;
  return out;
}

forward::ClosureOptions with_settings(forward::ClosureOptions o,
                                      const std::vector<std::string>& sets) {
  ValveParameters dummy;
  for (const auto& a : sets) forward::apply_setting(a, &o, &dummy);
  std::string err;
  if (!o.is_valid(&err)) throw Error("bench: " + err);
  return o;
}

/// The reference run's end surface: read from `file` when it holds a run of the same patient
/// with the same options, else simulated (and written to `file` if one is named).
LeafletGrid reference_surface(const Patient& p, const forward::ClosureOptions& ro,
                              const std::string& file, const Context& ctx) {
  // What decides the result: every option but how often states are recorded.
  auto physics = [](std::vector<std::pair<std::string, std::string>> o) {
    o.erase(std::remove_if(o.begin(), o.end(), [](const auto& kv) { return kv.first == "record_every"; }),
            o.end());
    return o;
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
  o.ruptured_marginal_chordae = p.truth->ruptured_marginal_chordae;
  o.progress = progress_line("  reference");
  const forward::ClosureResult r = forward::simulate_closure(p.sequence, p.truth->parameters, o);
  std::cout << r.summary.brief_report() << "\n";
  if (r.summary.status != forward::ClosureStatus::kConverged)
    throw Error("bench: the reference run failed: " + r.summary.reason);
  if (!file.empty()) {
    SimulationRecord rec = forward::make_simulation_record(r, ro, p.truth->parameters);
    rec.patient_id = p.id;
    rec.synthetic = true;
    rec.provenance.version = kVersion;
    rec.provenance.command = ctx.command_line;
    rec.provenance.created_utc = utc_now_iso8601();
    rec.provenance.seed = p.provenance.seed;
    write_simulation_file(file, rec);
    std::cout << "wrote the reference to " << file << "\n";
  }
  return r.samples.back().la_surface;
}

/// One randomized case of bench stability, drawn in order from the sweep's generator.
struct StabilityCase {
  Patient patient;
  ValveParameters parameters;
  forward::ClosureOptions options;
  std::uint64_t patient_seed = 0;
  std::string anatomy = "clean";
};

StabilityCase draw_stability_case(Rng& rng, const forward::ClosureOptions& base) {
  StabilityCase c;
  c.patient_seed = 5000 + static_cast<std::uint64_t>(rng.uniform_int(0, 1000000));
  c.patient = make_virtual_patient(c.patient_seed);
  Patient& p = c.patient;
  ValveParameters& par = c.parameters;
  par = p.truth->parameters;
  for (double& f : par.restlength_factor) f = rng.uniform(0.5, 1.5);
  par.marginal_stiffness_scale = std::exp(rng.uniform(std::log(0.2), std::log(5.0)));
  par.basal_stiffness_scale = std::exp(rng.uniform(std::log(0.2), std::log(5.0)));
  par.al_modulus_scale = std::exp(rng.uniform(std::log(0.2), std::log(5.0)));
  par.pl_modulus_scale = std::exp(rng.uniform(std::log(0.2), std::log(5.0)));
  par.peak_pressure_mpa = units::mmhg_to_mpa(rng.uniform(0.0, 200.0));
  c.options = base;
  c.options.dt = std::exp(rng.uniform(std::log(0.001), std::log(0.1)));
  const double a = rng.uniform();
  ValveFrame& ed = p.sequence.frames[p.sequence.end_diastole];
  if (a < 0.17) {
    c.anatomy = "noisy";
    const double sd = rng.uniform(0.3, 1.0);
    for (int f = 0; f < p.sequence.num_frames(); ++f) {
      if (!p.sequence.frames[f].la_surface) continue;
      auto& P = p.sequence.frames[f].la_surface->points();
      for (Eigen::Index k = p.sequence.ures; k < P.rows(); ++k)
        for (int d = 0; d < 3; ++d) P(k, d) += rng.normal(0.0, sd);
    }
  } else if (a < 0.33) {
    c.anatomy = "degenerate";
    // Collapse two neighbouring columns onto one another.
    auto& P = ed.la_surface->points();
    const int U = ed.la_surface->ures(), u = rng.uniform_int(1, U - 2);
    for (int v = 1; v < ed.la_surface->vres(); ++v) P.row(v * U + u + 1) = P.row(v * U + u);
  }
  return c;
}

/// Runs one case; never throws. Returns its row of the JSON table.
json run_stability_case(const StabilityCase& c) {
  std::string outcome, reason;
  double wall = 0.0;
  try {
    const forward::ClosureResult r = forward::simulate_closure(c.patient.sequence, c.parameters, c.options);
    wall = r.summary.wall_s;
    bool finite = r.positions.allFinite();
    for (const auto& s : r.samples) finite = finite && s.la_surface.points().allFinite();
    if (!finite) {
      outcome = "nonfinite_output";
    } else if (r.summary.status == forward::ClosureStatus::kConverged) {
      outcome = "converged";
    } else {
      outcome = "clean_failure";
      reason = r.summary.reason;
    }
  } catch (const Error& e) {
    outcome = "clean_failure";
    reason = e.what();
  } catch (const std::exception& e) {
    outcome = "crash";
    reason = e.what();
  } catch (...) {
    outcome = "crash";
    reason = "unknown exception";
  }
  return {{"patient_seed", c.patient_seed},
          {"dt", c.options.dt},
          {"wall_s", wall},
          {"peak_pressure_mmhg", units::mpa_to_mmhg(c.parameters.peak_pressure_mpa)},
          {"anatomy", c.anatomy},
          {"outcome", outcome},
          {"reason", reason}};
}

std::string failure_kind(const std::string& reason) {
  if (reason.find("inverted") != std::string::npos) return "inverted element";
  if (reason.find("pass through") != std::string::npos) return "leaflet crossing";
  if (reason.find("degenerate") != std::string::npos) return "degenerate anatomy";
  if (reason.find("linear solver") != std::string::npos) return "linear solver";
  if (reason.find("non-finite") != std::string::npos) return "non-finite values";
  return "other";
}

/// bench stability: `runs` cases drawn in order from `seed` and simulated `threads` at a time.
/// The JSON file is rewritten every 10 finished cases (marked incomplete) so that an
/// interrupted sweep started again with the same seed and settings resumes where it was.
int run_stability(const Context& ctx, const std::string& json_path, int runs, unsigned seed,
                  int threads, const std::vector<std::string>& sets) {
  const forward::ClosureOptions base = with_settings({}, sets);
  std::vector<json> rows(static_cast<std::size_t>(runs));
  int resumed = 0;
  if (!json_path.empty() && std::filesystem::exists(json_path)) {
    try {
      std::ifstream f(json_path);
      const json old = json::parse(f);
      if (old.value("seed", 0u) == seed && old.value("settings", json::array()) == json(sets)) {
        const json& cases = old.at("cases");
        for (std::size_t i = 0; i < cases.size() && i < rows.size(); ++i) {
          if (cases[i].is_null()) continue;
          rows[i] = cases[i];
          ++resumed;
        }
      }
    } catch (const std::exception& e) {
      std::cout << json_path << ": not a bench stability file (" << e.what()
                << "); starting afresh\n";
    }
    if (resumed > 0) std::cout << "resuming: " << resumed << " runs from " << json_path << "\n";
  }
  auto summarize = [&](bool complete) {
    int converged = 0, clean = 0, crashes = 0, nonfinite = 0, done = 0;
    json reasons = json::object();
    for (const json& r : rows) {
      if (r.is_null()) continue;
      ++done;
      const std::string o = r.at("outcome");
      if (o == "converged") ++converged;
      else if (o == "clean_failure") ++clean;
      else if (o == "crash") ++crashes;
      else ++nonfinite;
      const std::string reason = r.value("reason", "");
      if (!reason.empty()) {
        const std::string k = failure_kind(reason);
        reasons[k] = reasons.value(k, 0) + 1;
      }
    }
    return json{{"runs", runs},
                {"finished", done},
                {"complete", complete},
                {"converged", converged},
                {"clean_failures", clean},
                {"crashes", crashes},
                {"nonfinite_outputs", nonfinite},
                {"clean_failure_reasons", reasons},
                {"seed", seed},
                {"settings", sets},
                {"threads", threads},
                {"synthetic", true},
                {"cases", rows},
                {"provenance", provenance(ctx)}};
  };

  Rng rng(seed);
  std::mutex m;
  int next = 0, since_write = 0;
  auto worker = [&] {
    for (;;) {
      std::optional<StabilityCase> c;
      int i = 0;
      {
        // Cases are drawn in index order under the lock, so case i is the same whichever
        // thread runs it (and whether or not it was already run: its draws are still made).
        std::lock_guard<std::mutex> lock(m);
        while (next < runs) {
          i = next++;
          StabilityCase drawn = draw_stability_case(rng, base);
          if (rows[static_cast<std::size_t>(i)].is_null()) {
            c = std::move(drawn);
            break;
          }
        }
        if (!c) return;
      }
      json row = run_stability_case(*c);
      std::lock_guard<std::mutex> lock(m);
      rows[static_cast<std::size_t>(i)] = std::move(row);
      const json s = summarize(false);
      std::cout << "\r" << s.at("finished").get<int>() << "/" << runs << ": "
                << s.at("converged").get<int>() << " converged, "
                << s.at("clean_failures").get<int>() << " clean failures, "
                << s.at("crashes").get<int>() << " crashes, " << s.at("nonfinite_outputs").get<int>()
                << " non-finite" << std::flush;
      if (++since_write >= 10 && !json_path.empty()) {
        since_write = 0;
        write_json_file(json_path, s, 1);
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
  const json j = summarize(true);
  std::cout << "\nclean failures by reason: " << j.at("clean_failure_reasons").dump() << "\n";
  write_json(json_path, j);
  return j.at("crashes").get<int>() == 0 && j.at("nonfinite_outputs").get<int>() == 0 ? 0 : 5;
}

}  // namespace

void register_bench(CLI::App& app, Context& ctx) {
  auto* bench = app.add_subcommand("bench", "Benchmarks: time and the error it costs");
  register_bench_calibrate(*bench, ctx);
  register_bench_detect(*bench, ctx);
  register_bench_import(*bench, ctx);
  bench->require_subcommand(1);

  // ---- bench closure ----------------------------------------------------------------------
  {
    auto* cmd = bench->add_subcommand(
        "closure", "One closure of the default virtual patient, timed, against a reference run");
    cmd->footer(
        "Example:\n  mvtwin bench closure --json closure.json --ref-file closure_ref.h5\n"
        "The timed run uses the paper's settings (ures = vres = 30, dt = 0.01 s) unless --set says\n"
        "otherwise and is repeated (--repeat; wall_s is the fastest, all are listed). The\n"
        "reference is a finer, smaller-step run (--ref-set); error_mean_mm / error_max_mm are\n"
        "the symmetric point-to-mesh distances between the end surfaces. --ref-file keeps the\n"
        "reference as a simulation file and reuses it when its settings match.");
    auto json_path = std::make_shared<std::string>();
    auto ref_file = std::make_shared<std::string>();
    auto sets = std::make_shared<std::vector<std::string>>();
    auto ref_sets = std::make_shared<std::vector<std::string>>(kReferenceSettings);
    auto seed = std::make_shared<unsigned>(1);
    auto repeat = std::make_shared<int>(3);
    cmd->add_option("--json", *json_path, "write the figures here");
    cmd->add_option("--set", *sets, "name=value for the timed run (repeatable)");
    cmd->add_option("--ref-set", *ref_sets, "name=value for the reference run")
        ->default_str(join(kReferenceSettings));
    cmd->add_option("--ref-file", *ref_file, "reference simulation file to reuse or write");
    cmd->add_option("--seed", *seed, "virtual patient")->default_val(1);
    cmd->add_option("--repeat", *repeat, "timed runs (the fastest is reported)")->default_val(3);
    cmd->callback([=, &ctx] {
      ctx.run = [=, &ctx] {
        if (*repeat < 1) throw Error("bench closure: --repeat must be >= 1");
        const Patient p = make_virtual_patient(*seed);
        const forward::ClosureOptions o = with_settings({}, *sets);
        const forward::ClosureOptions ro = with_settings({}, *ref_sets);
        std::vector<double> walls;
        Run a;
        for (int k = 0; k < *repeat; ++k) {
          std::cout << "timed run " << k + 1 << "/" << *repeat << " ..." << std::endl;
          Run r = run(p, o);
          walls.push_back(r.wall_s);
          if (k == 0 || r.wall_s < a.wall_s) a = std::move(r);
        }
        std::cout << a.result.summary.brief_report() << "\n";
        const LeafletGrid ref_surface = reference_surface(p, ro, *ref_file, ctx);
        const DistanceStats e = symmetric_surface_distance(
            a.result.samples.back().la_surface.triangulate(), ref_surface.triangulate()).symmetric;
        std::vector<double> sorted = walls;
        std::sort(sorted.begin(), sorted.end());
        json j = summary_json(a);
        j["wall_s"] = sorted.front();
        j["wall_s_median"] = sorted[sorted.size() / 2];
        j["wall_s_all"] = walls;
        j["error_mean_mm"] = e.mean;
        j["error_sd_mm"] = e.sd;
        j["error_p95_mm"] = e.p95;
        j["error_max_mm"] = e.max;
        j["reference_settings"] = *ref_sets;
        j["settings"] = forward::describe_options(o);
        j["patient_seed"] = *seed;
        j["synthetic"] = true;
        j["provenance"] = provenance(ctx);
        const auto& s = a.result.summary;
        std::cout << "wall_s " << sorted.front() << " (median " << sorted[sorted.size() / 2]
                  << " of " << walls.size() << ")  steps " << s.steps << "  dofs " << s.dofs
                  << "  tets " << s.elements << "  assembly_s " << s.assembly_s << "  solve_s "
                  << s.solve_s << "  contact_s " << s.contact_s << "\nerror_mean_mm " << e.mean
                  << "  error_max_mm " << e.max << " (against the reference)\n";
        write_json(*json_path, j);
        return 0;
      };
    });
  }

  // ---- bench solvers -----------------------------------------------------------------------
  {
    auto* cmd = bench->add_subcommand(
        "solvers", "Linear solvers at equal accuracy: time and error of each");
    cmd->footer(
        "Example:\n  mvtwin bench solvers --json solvers.json --ref-file closure_ref.h5\n"
        "The default patient's closure at the paper's settings with each linear solver: a\n"
        "factorization every step (CHOLMOD supernodal, CHOLMOD simplicial, Eigen LDLT) and the\n"
        "reused factorization as a preconditioner (with and without the rotation of the\n"
        "factor), each at linear tolerances 0.1 and 1e-3; error against the reference run.");
    auto json_path = std::make_shared<std::string>();
    auto ref_file = std::make_shared<std::string>();
    auto sets = std::make_shared<std::vector<std::string>>();
    auto ref_sets = std::make_shared<std::vector<std::string>>(kReferenceSettings);
    auto seed = std::make_shared<unsigned>(1);
    cmd->add_option("--json", *json_path, "write the figures here");
    cmd->add_option("--set", *sets, "name=value for every run (repeatable)");
    cmd->add_option("--ref-set", *ref_sets, "name=value for the reference run")
        ->default_str(join(kReferenceSettings));
    cmd->add_option("--ref-file", *ref_file, "reference simulation file to reuse or write");
    cmd->add_option("--seed", *seed, "virtual patient")->default_val(1);
    cmd->callback([=, &ctx] {
      ctx.run = [=, &ctx] {
        const Patient p = make_virtual_patient(*seed);
        const LeafletGrid ref = reference_surface(p, with_settings({}, *ref_sets), *ref_file, ctx);
        const std::vector<std::vector<std::string>> variants = {
            {"solver=cholmod-supernodal"},
            {"solver=cholmod-simplicial"},
            {"solver=eigen-ldlt"},
            {"solver=reused-factor-pcg", "rotated_preconditioner=on"},
            {"solver=reused-factor-pcg", "rotated_preconditioner=off"}};
        json rows = json::array();
        std::cout << "solver                       tol     wall_s  solve_s  factorizations  "
                     "pcg_iterations  error_mean_mm  error_max_mm\n";
        for (const char* tol : {"0.1", "0.001"}) {
          for (const auto& v : variants) {
            std::vector<std::string> all = *sets;
            all.insert(all.end(), v.begin(), v.end());
            all.push_back(std::string("pcg_tolerance=") + tol);
            const Run r = run(p, with_settings({}, all));
            const auto& s = r.result.summary;
            const DistanceStats e =
                symmetric_surface_distance(r.result.samples.back().la_surface.triangulate(),
                                           ref.triangulate()).symmetric;
            json row = summary_json(r);
            row["variant"] = v;
            row["pcg_tolerance"] = std::stod(tol);
            row["pcg_iterations"] = s.pcg_iterations;
            row["factorize_s"] = s.factorize_s;
            row["error_mean_mm"] = e.mean;
            row["error_max_mm"] = e.max;
            rows.push_back(row);
            std::string name = v[0].substr(7);
            if (v.size() > 1) name += v[1] == "rotated_preconditioner=on" ? " (rotated)" : " (plain)";
            char line[240];
            std::snprintf(line, sizeof line, "%-28s %-6s %7.2f %8.2f %15d %15d %14.3f %13.3f%s\n",
                          name.c_str(), tol, s.wall_s, s.solve_s, s.factorizations,
                          s.pcg_iterations, e.mean, e.max,
                          s.status == forward::ClosureStatus::kConverged
                              ? ""
                              : ("  FAILED: " + s.reason).c_str());
            std::cout << line << std::flush;
          }
        }
        json j{{"runs", rows},
               {"patient_seed", *seed},
               {"synthetic", true},
               {"reference_settings", *ref_sets},
               {"provenance", provenance(ctx)}};
        write_json(*json_path, j);
        return 0;
      };
    });
  }

  // ---- bench accuracy ---------------------------------------------------------------------
  {
    auto* cmd = bench->add_subcommand(
        "accuracy", "Time against error over resolution, layers and time step");
    cmd->footer(
        "Example:\n  mvtwin bench accuracy --json accuracy.json\n"
        "One factor at a time around the default (ures = vres = 30, 1 layer, dt = 0.01 s):\n"
        "ures in {20, 30, 40, 50}, vres in {10, 20, 30}, layers in {1, 2, 3}, dt in {0.1, 0.05,\n"
        "0.01, 0.001}; every run is compared with the finest run of its series.\n"
        "--full runs the whole grid instead (hours).");
    auto json_path = std::make_shared<std::string>();
    auto seed = std::make_shared<unsigned>(1);
    auto full = std::make_shared<bool>(false);
    auto base_sets = std::make_shared<std::vector<std::string>>();
    cmd->add_option("--json", *json_path, "write the figures here");
    cmd->add_option("--seed", *seed, "virtual patient")->default_val(1);
    cmd->add_option("--set", *base_sets, "name=value applied to every run");
    cmd->add_flag("--full", *full, "the full grid, not one factor at a time");
    cmd->callback([=, &ctx] {
      ctx.run = [=, &ctx] {
        const Patient p = make_virtual_patient(*seed);
        const forward::ClosureOptions base = with_settings({}, *base_sets);
        struct Series {
          std::string factor;
          std::vector<std::string> values;
        };
        std::vector<Series> series = {{"ures", {"20", "30", "40", "50"}},
                                      {"vres", {"10", "20", "30"}},
                                      {"layers", {"1", "2", "3"}},
                                      {"dt", {"0.1", "0.05", "0.01", "0.001"}}};
        json rows = json::array();
        std::cout << "factor  value   wall_s   steps    dofs  error_mean_mm  error_max_mm  status\n";
        auto one = [&](const std::vector<std::string>& sets) {
          return run(p, with_settings(base, sets));
        };
        if (*full) {
          std::vector<std::vector<std::string>> combos;
          for (const auto& u : series[0].values)
            for (const auto& v : series[1].values)
              for (const auto& l : series[2].values)
                for (const auto& d : series[3].values)
                  combos.push_back({"ures=" + u, "vres=" + v, "layers=" + l, "dt=" + d});
          std::vector<Run> runs;
          for (const auto& c : combos) {
            runs.push_back(one(c));
            std::cout << "." << std::flush;
          }
          const Run& ref = runs.back();  // finest: last of every list
          for (size_t i = 0; i < runs.size(); ++i) {
            const DistanceStats e = end_error(runs[i], ref);
            json r = summary_json(runs[i]);
            r["settings"] = combos[i];
            r["error_mean_mm"] = e.mean;
            r["error_max_mm"] = e.max;
            rows.push_back(r);
          }
          std::cout << "\n";
        } else {
          for (const Series& s : series) {
            std::vector<Run> runs;
            for (const auto& v : s.values) runs.push_back(one({s.factor + "=" + v}));
            const Run& ref = runs.back();
            for (size_t i = 0; i < runs.size(); ++i) {
              const bool ok = runs[i].result.summary.status == forward::ClosureStatus::kConverged;
              const DistanceStats e = end_error(runs[i], ref);
              json r = summary_json(runs[i]);
              r["factor"] = s.factor;
              r["value"] = s.values[i];
              r["error_mean_mm"] = e.mean;
              r["error_max_mm"] = e.max;
              rows.push_back(r);
              char line[200];
              std::snprintf(line, sizeof line, "%-7s %-6s %7.2f %7d %7d %14.3f %13.3f  %s\n",
                            s.factor.c_str(), s.values[i].c_str(), runs[i].wall_s,
                            runs[i].result.summary.steps, runs[i].result.summary.dofs, e.mean,
                            e.max, ok ? "converged" : runs[i].result.summary.reason.c_str());
              std::cout << line << std::flush;
            }
          }
        }
        json j{{"runs", rows},
               {"patient_seed", *seed},
               {"synthetic", true},
               {"base_settings", forward::describe_options(base)},
               {"reference", "the last (finest) value of each series"},
               {"provenance", provenance(ctx)}};
        write_json(*json_path, j);
        return 0;
      };
    });
  }

  // ---- bench stability --------------------------------------------------------------------
  {
    auto* cmd = bench->add_subcommand("stability", "Randomized stress test of the simulator");
    cmd->footer(
        "Example:\n  mvtwin bench stability --runs 1000 --json stability.json\n"
        "Each run draws a virtual patient and: rest-length factors 0.5-1.5, chordae stiffness\n"
        "x0.2-5, leaflet moduli x0.2-5, peak pressure 0-200 mmHg, dt 0.001-0.1 s, and in a\n"
        "third of the runs noisy (0.3-1 mm) or degenerate (collapsed columns) anatomy.\n"
        "Counts: converged, clean failures (a status with a reason, or a named input error),\n"
        "crashes (any other exception) and non-finite outputs. Coarse models (--set) keep it\n"
        "fast.");
    auto json_path = std::make_shared<std::string>();
    auto runs = std::make_shared<int>(50);
    auto seed = std::make_shared<unsigned>(7);
    auto threads = std::make_shared<int>(1);
    auto sets = std::make_shared<std::vector<std::string>>(
        std::vector<std::string>{"ures=20", "vres=10"});
    cmd->add_option("--json", *json_path,
                    "write the figures here (rewritten every 10 runs; a run interrupted and "
                    "started again with the same seed and settings resumes from it)");
    cmd->add_option("--runs", *runs, "number of randomized runs")->default_val(50);
    cmd->add_option("--seed", *seed, "random seed")->default_val(7);
    cmd->add_option("--threads", *threads,
                    "runs simulated at once (each on one core; the draws, and so the cases, "
                    "do not depend on it)")
        ->default_val(1)
        ->check(CLI::Range(1, 64));
    cmd->add_option("--set", *sets, "name=value for every run")->default_str("ures=20 vres=10");
    cmd->callback([=, &ctx] {
      ctx.run = [=, &ctx] { return run_stability(ctx, *json_path, *runs, *seed, *threads, *sets); };
    });
  }
}

}  // namespace mvtwin::tools
