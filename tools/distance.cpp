// mvtwin distance (tools/distance.h).
#include "distance.h"

#include <iostream>

#include <nlohmann/json.hpp>

#include "exit_codes.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/point_to_mesh_distance.h"
#include "mvtwin/core/simulation_file.h"
#include "report.h"

namespace mvtwin::tools {

int run_distance(const DistanceArgs& a) {
  auto surface = [](const std::string& file, int frame) {
    if (mvtwin_file_format(file) == "mvtwin-simulation") {
      const SimulationRecord r = read_simulation_file(file);
      if (r.la_surface.empty()) throw Error(file + ": the simulation recorded no surface");
      return r.la_surface.back().triangulate();
    }
    const Patient p = read_patient(file, false);
    const ValveSequence& s = p.sequence;
    if (frame < 0) frame = s.first_closed >= 0 ? s.first_closed : 0;
    if (frame >= s.num_frames()) {
      throw Error(file + ": frame " + std::to_string(frame) + " does not exist (" +
                  std::to_string(s.num_frames()) + " frames)");
    }
    if (!s.frames[frame].la_surface) {
      throw Error(file + ": frame " + std::to_string(frame) + " has no leaflet surface");
    }
    return s.frames[frame].la_surface->triangulate();
  };
  const SymmetricDistance d =
      symmetric_surface_distance(surface(a.a, a.frame_a), surface(a.b, a.frame_b));
  if (a.json) {
    auto stats = [](const DistanceStats& x) {
      return nlohmann::json{{"mean_mm", x.mean},
                            {"sd_mm", x.sd},
                            {"p95_mm", x.p95},
                            {"max_mm", x.max},
                            {"n", x.count}};
    };
    std::cout << nlohmann::json{{"a", a.a},
                                {"b", a.b},
                                {"a_to_b", stats(d.a_to_b)},
                                {"b_to_a", stats(d.b_to_a)},
                                {"symmetric", stats(d.symmetric)}}
                     .dump(2)
              << "\n";
    return kExitOk;
  }
  auto line = [](const char* what, const DistanceStats& x) {
    std::cout << what << fixed(x.mean) << " +- " << fixed(x.sd) << " mm (95th pct " << fixed(x.p95)
              << ", max " << fixed(x.max) << ", n=" << x.count << ")\n";
  };
  line("A -> B:    ", d.a_to_b);
  line("B -> A:    ", d.b_to_a);
  line("symmetric: ", d.symmetric);
  return kExitOk;
}

void register_distance(CLI::App& app, Context& ctx) {
  auto* cmd = app.add_subcommand("distance", "Point-to-mesh distance between two LA surfaces");
  cmd->footer(
      "Examples:\n  mvtwin distance closed.h5 observed.h5\n  mvtwin distance closed.h5 "
      "closed_dt.h5\n  mvtwin distance closed.h5 observed.h5 --json\n"
      "A and B are patient files or simulation results (their end surface). Patient frames\n"
      "default to the first closed frame (else frame 0); distances go from the vertices of\n"
      "one surface to the triangles of the other, both ways.");
  auto a = std::make_shared<DistanceArgs>();
  cmd->add_option("A", a->a, "first patient or simulation file")->required();
  cmd->add_option("B", a->b, "second patient or simulation file")->required();
  cmd->add_option("--frame-a", a->frame_a, "frame of A (default: first closed, else 0)");
  cmd->add_option("--frame-b", a->frame_b, "frame of B (default: first closed, else 0)");
  cmd->add_flag("--json", a->json,
                "print the figures as JSON at full precision (a_to_b, b_to_a, symmetric: "
                "mean_mm, sd_mm, p95_mm, max_mm, n)");
  run_on_parse(cmd, ctx, a, run_distance);
}

}  // namespace mvtwin::tools
