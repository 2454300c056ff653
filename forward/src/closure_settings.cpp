#include "mvtwin/forward/closure_settings.h"

#include <algorithm>
#include <charconv>
#include <cstdlib>
#include <functional>
#include <map>
#include <sstream>
#include <vector>

#include "mvtwin/core/error.h"
#include "mvtwin/core/units.h"

namespace mvtwin::forward {
namespace {

double to_double(const std::string& name, const std::string& v) {
  double x = 0;
  const auto [p, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
  if (ec != std::errc() || p != v.data() + v.size()) {
    throw Error("--set " + name + ": '" + v + "' is not a number");
  }
  return x;
}
int to_int(const std::string& name, const std::string& v) {
  int x = 0;
  const auto [p, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
  if (ec != std::errc() || p != v.data() + v.size()) {
    throw Error("--set " + name + ": '" + v + "' is not an integer");
  }
  return x;
}
bool to_bool(const std::string& name, const std::string& v) {
  if (v == "1" || v == "true" || v == "on" || v == "yes") return true;
  if (v == "0" || v == "false" || v == "off" || v == "no") return false;
  throw Error("--set " + name + ": '" + v + "' is not on/off");
}
std::string str(double x) {
  std::ostringstream os;
  os.precision(10);
  os << x;
  return os.str();
}

struct Field {
  std::function<void(ClosureOptions&, const std::string&, const std::string&)> set;
  std::function<std::string(const ClosureOptions&)> get;
};

const std::map<std::string, Field>& fields() {
  static const std::map<std::string, Field> f = [] {
    std::map<std::string, Field> m;
    auto dbl = [&](const std::string& n, auto member) {
      m[n] = {[member](ClosureOptions& o, const std::string& k, const std::string& v) {
                member(o) = to_double(k, v);
              },
              [member](const ClosureOptions& o) {
                return str(member(const_cast<ClosureOptions&>(o)));
              }};
    };
    auto integer = [&](const std::string& n, auto member) {
      m[n] = {[member](ClosureOptions& o, const std::string& k, const std::string& v) {
                member(o) = to_int(k, v);
              },
              [member](const ClosureOptions& o) {
                return std::to_string(member(const_cast<ClosureOptions&>(o)));
              }};
    };
    auto boolean = [&](const std::string& n, auto member) {
      m[n] = {[member](ClosureOptions& o, const std::string& k, const std::string& v) {
                member(o) = to_bool(k, v);
              },
              [member](const ClosureOptions& o) {
                return std::string(member(const_cast<ClosureOptions&>(o)) ? "on" : "off");
              }};
    };
    dbl("dt", [](ClosureOptions& o) -> double& { return o.dt; });
    dbl("step_error_mm", [](ClosureOptions& o) -> double& { return o.step_error_mm; });
    dbl("max_dt", [](ClosureOptions& o) -> double& { return o.max_dt; });
    dbl("stretch", [](ClosureOptions& o) -> double& { return o.stretch; });
    dbl("settle_mm", [](ClosureOptions& o) -> double& { return o.settle_mm; });
    dbl("settle_max_dt", [](ClosureOptions& o) -> double& { return o.settle_max_dt; });
    dbl("settle_max_s", [](ClosureOptions& o) -> double& { return o.settle_max_s; });
    dbl("static_tolerance", [](ClosureOptions& o) -> double& { return o.static_tolerance; });
    dbl("static_step_mm", [](ClosureOptions& o) -> double& { return o.static_step_mm; });
    dbl("static_start_mm", [](ClosureOptions& o) -> double& { return o.static_start_mm; });
    dbl("density", [](ClosureOptions& o) -> double& { return o.density; });
    dbl("rayleigh_mass", [](ClosureOptions& o) -> double& { return o.rayleigh_mass; });
    dbl("rayleigh_stiffness", [](ClosureOptions& o) -> double& { return o.rayleigh_stiffness; });
    dbl("newton_tolerance", [](ClosureOptions& o) -> double& { return o.newton_tolerance; });
    dbl("pcg_tolerance", [](ClosureOptions& o) -> double& { return o.solver.pcg_tolerance; });
    dbl("contact_alarm_mm", [](ClosureOptions& o) -> double& { return o.contact.alarm_mm; });
    dbl("contact_distance_mm", [](ClosureOptions& o) -> double& { return o.contact.contact_mm; });
    dbl("contact_friction", [](ClosureOptions& o) -> double& { return o.contact.friction; });
    dbl("inversion_guard", [](ClosureOptions& o) -> double& { return o.inversion_guard; });
    dbl("contact_ccd_depth_mm",
        [](ClosureOptions& o) -> double& { return o.contact.ccd_depth_mm; });
    dbl("contact_smooth_mm", [](ClosureOptions& o) -> double& { return o.contact.smooth_mm; });
    dbl("contact_wall_factor", [](ClosureOptions& o) -> double& { return o.contact.wall_factor; });
    dbl("contact_stiffness_factor",
        [](ClosureOptions& o) -> double& { return o.contact.stiffness_factor; });
    dbl("al_thickness_mm", [](ClosureOptions& o) -> double& { return o.model.al_thickness_mm; });
    dbl("pl_thickness_mm", [](ClosureOptions& o) -> double& { return o.model.pl_thickness_mm; });
    integer("ures", [](ClosureOptions& o) -> int& { return o.model.ures; });
    integer("vres", [](ClosureOptions& o) -> int& { return o.model.vres; });
    integer("layers", [](ClosureOptions& o) -> int& { return o.model.layers; });
    integer("grasp_refine", [](ClosureOptions& o) -> int& { return o.model.refine_factor; });
    integer("marginal_chordae", [](ClosureOptions& o) -> int& { return o.model.marginal_chordae; });
    integer("newton_iterations", [](ClosureOptions& o) -> int& { return o.newton_iterations; });
    integer("settle_newton_iterations",
            [](ClosureOptions& o) -> int& { return o.settle_newton_iterations; });
    integer("settle_newton_max_iterations",
            [](ClosureOptions& o) -> int& { return o.settle_newton_max_iterations; });
    integer("static_max_iterations",
            [](ClosureOptions& o) -> int& { return o.static_max_iterations; });
    integer("pcg_max_iterations",
            [](ClosureOptions& o) -> int& { return o.solver.pcg_max_iterations; });
    integer("refactor_iterations",
            [](ClosureOptions& o) -> int& { return o.solver.refactor_iterations; });
    integer("max_step_halvings", [](ClosureOptions& o) -> int& { return o.max_step_halvings; });
    integer("threads", [](ClosureOptions& o) -> int& { return o.threads; });
    integer("record_every", [](ClosureOptions& o) -> int& { return o.record_every; });
    integer("orifice_refine", [](ClosureOptions& o) -> int& { return o.orifice_refine; });
    boolean("single_precision_preconditioner",
            [](ClosureOptions& o) -> bool& { return o.solver.single_precision_preconditioner; });
    boolean("single_precision_factorization",
            [](ClosureOptions& o) -> bool& { return o.solver.single_precision_factorization; });
    boolean("rotated_preconditioner",
            [](ClosureOptions& o) -> bool& { return o.solver.rotated_preconditioner; });
    boolean("warm_start", [](ClosureOptions& o) -> bool& { return o.solver.warm_start; });
    boolean("static_rest", [](ClosureOptions& o) -> bool& { return o.static_rest; });
    boolean("curved", [](ClosureOptions& o) -> bool& { return o.model.curved; });
    boolean("contact", [](ClosureOptions& o) -> bool& { return o.contact.enabled; });
    boolean("contact_ccd", [](ClosureOptions& o) -> bool& { return o.contact.ccd; });
    boolean("annulus_motion", [](ClosureOptions& o) -> bool& { return o.annulus_motion; });
    boolean("papillary_motion", [](ClosureOptions& o) -> bool& { return o.papillary_motion; });
    m["order"] = {[](ClosureOptions& o, const std::string& k, const std::string& v) {
                    if (v == "linear") {
                      o.model.order = TetOrder::kLinear;
                    } else if (v == "quadratic") {
                      o.model.order = TetOrder::kQuadratic;
                    } else {
                      throw Error("--set " + k + ": '" + v + "' is not linear or quadratic");
                    }
                  },
                  [](const ClosureOptions& o) {
                    return std::string(o.model.order == TetOrder::kLinear ? "linear" : "quadratic");
                  }};
    m["solver"] = {[](ClosureOptions& o, const std::string& k, const std::string& v) {
                     if (!parse_linear_solver(v, &o.solver.kind)) {
                       throw Error("--set " + k + ": unknown solver '" + v + "'");
                     }
                   },
                   [](const ClosureOptions& o) { return std::string(name(o.solver.kind)); }};
    // A list: clips as "s_a,t_a,s_p,t_p[,k[,width,arm,spacer[,insertion_a,insertion_p[,device]]]]"
    // separated by ";".
    m["clips"] = {
        [](ClosureOptions& o, const std::string& k, const std::string& v) {
          o.clips.clear();
          std::stringstream all(v);
          std::string one;
          while (std::getline(all, one, ';')) {
            if (one.empty()) continue;
            std::vector<std::string> parts;
            std::stringstream ps(one);
            std::string item;
            while (std::getline(ps, item, ',')) parts.push_back(item);
            const size_t n = parts.size();
            if (n != 4 && n != 5 && n != 8 && n != 10 && n != 11) {
              throw Error("--set " + k +
                          ": a clip is s_anterior,t_anterior,s_posterior,t_posterior"
                          "[,stiffness N/mm[,width,arm length,spacer mm[,anterior and posterior "
                          "insertion mm[,device]]]], got '" +
                          one + "'");
            }
            ClipOptions c;
            c.anterior_s = to_double(k, parts[0]);
            c.anterior_t = to_double(k, parts[1]);
            c.posterior_s = to_double(k, parts[2]);
            c.posterior_t = to_double(k, parts[3]);
            if (n >= 5) c.stiffness_n_per_mm = to_double(k, parts[4]);
            if (n >= 8) {
              c.width_mm = to_double(k, parts[5]);
              c.arm_length_mm = to_double(k, parts[6]);
              c.spacer_mm = to_double(k, parts[7]);
            }
            if (n >= 10) {
              c.anterior_insertion_mm = to_double(k, parts[8]);
              c.posterior_insertion_mm = to_double(k, parts[9]);
            }
            if (n == 11) c.device = parts[10];
            o.clips.push_back(c);
          }
        },
        [](const ClosureOptions& o) {
          std::string out;
          for (const ClipOptions& c : o.clips) {
            out += (out.empty() ? "" : ";") + str(c.anterior_s) + "," + str(c.anterior_t) + "," +
                   str(c.posterior_s) + "," + str(c.posterior_t) + "," + str(c.stiffness_n_per_mm);
            if (c.width_mm > 0) {
              out += "," + str(c.width_mm) + "," + str(c.arm_length_mm) + "," + str(c.spacer_mm) +
                     "," + str(c.anterior_insertion_mm) + "," + str(c.posterior_insertion_mm) +
                     (c.device.empty() ? "" : "," + c.device);
            }
          }
          return out;
        }};
    dbl("clip_closing_s", [](ClosureOptions& o) -> double& { return o.clip_closing_s; });
    return m;
  }();
  return f;
}

}  // namespace

namespace {

std::pair<std::string, std::string> split_assignment(const std::string& a) {
  const auto eq = a.find('=');
  if (eq == std::string::npos || eq == 0) throw Error("--set needs name=value, got '" + a + "'");
  return {a.substr(0, eq), a.substr(eq + 1)};
}

std::string option_names() {
  std::string known;
  for (const auto& [n, f] : fields()) known += " " + n;
  return known;
}

std::string parameter_names() {
  std::string known;
  ValveParameters p;
  p.for_each([&](const std::string& n, double&, const char*) { known += " " + n; });
  return known + " peak_pressure_mmhg";
}

}  // namespace

bool is_option_name(const std::string& name) { return fields().count(name) > 0; }

bool is_parameter_name(const std::string& name) {
  if (name == "peak_pressure_mmhg") return true;
  bool found = false;
  ValveParameters p;
  p.for_each([&](const std::string& n, double&, const char*) { found |= n == name; });
  return found;
}

void apply_option(const std::string& a, ClosureOptions* o, const std::string& context) {
  const auto [name, value] = split_assignment(a);
  if (const auto it = fields().find(name); it != fields().end()) {
    it->second.set(*o, name, value);
    return;
  }
  if (is_parameter_name(name))
    throw Error("--set " + name + ": a patient parameter, not a simulation option (" + context +
                ")");
  throw Error("--set: unknown option '" + name + "'; known:" + option_names());
}

void apply_parameter(const std::string& a, ValveParameters* p) {
  const auto [name, value] = split_assignment(a);
  if (name == "peak_pressure_mmhg") {
    p->peak_pressure_mpa = units::mmhg_to_mpa(to_double(name, value));
    return;
  }
  bool found = false;
  p->for_each([&](const std::string& n, double& x, const char*) {
    if (n == name) {
      x = to_double(name, value);
      found = true;
    }
  });
  if (found) return;
  if (is_option_name(name))
    throw Error("--set " + name + ": a simulation option, not a patient parameter");
  throw Error("--set: unknown parameter '" + name + "'; known:" + parameter_names());
}

void apply_setting(const std::string& a, ClosureOptions* o, ValveParameters* p) {
  const std::string name = split_assignment(a).first;
  if (is_option_name(name)) return apply_option(a, o);
  if (is_parameter_name(name)) return apply_parameter(a, p);
  throw Error("--set: unknown name '" + name + "'; known options:" + option_names() +
              "; known parameters:" + parameter_names());
}

std::vector<std::pair<std::string, std::string>> describe_options(const ClosureOptions& o) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& [n, f] : fields()) {
    // The static solve's options only where it is on: descriptions (result files, study
    // folders' configurations) made before it existed stay the same.
    if (!o.static_rest && n.rfind("static_", 0) == 0) continue;
    // Likewise the crossing depth at 0, every pass a crossing as before it existed.
    if (n == "contact_ccd_depth_mm" && o.contact.ccd_depth_mm == 0) continue;
    // And the smooth contact distance, which only the static solve uses, at 0 or without it.
    if (n == "contact_smooth_mm" && (o.contact.smooth_mm == 0 || !o.static_rest)) continue;
    // And settling's adaptive iterations where they cannot adapt (as before they existed).
    if (n == "settle_newton_max_iterations" &&
        o.settle_newton_max_iterations <= o.settle_newton_iterations)
      continue;
    out.emplace_back(n, f.get(o));
  }
  return out;
}

bool affects_results(const std::string& option_name) { return option_name != "threads"; }

std::vector<std::pair<std::string, std::string>> result_options(
    std::vector<std::pair<std::string, std::string>> out) {
  std::erase_if(out, [](const auto& kv) { return !affects_results(kv.first); });
  const auto settle =
      std::find_if(out.begin(), out.end(), [](const auto& kv) { return kv.first == "settle_mm"; });
  if (settle == out.end() || !(std::strtod(settle->second.c_str(), nullptr) > 0)) {
    std::erase_if(out, [](const auto& kv) { return kv.first.rfind("settle_", 0) == 0; });
  }
  // Likewise the static solve's options while it is off (descriptions made before it existed).
  const auto stat = std::find_if(out.begin(), out.end(),
                                 [](const auto& kv) { return kv.first == "static_rest"; });
  if (stat == out.end() || stat->second != "on") {
    std::erase_if(out, [](const auto& kv) {
      return kv.first.rfind("static_", 0) == 0 || kv.first == "contact_smooth_mm";
    });
  }
  std::erase_if(out, [](const auto& kv) {
    return kv.first == "contact_smooth_mm" && std::strtod(kv.second.c_str(), nullptr) == 0;
  });
  std::erase_if(out, [](const auto& kv) {
    return kv.first == "contact_ccd_depth_mm" && std::strtod(kv.second.c_str(), nullptr) == 0;
  });
  return out;
}

std::vector<std::pair<std::string, std::string>> describe_result_options(const ClosureOptions& o) {
  return result_options(describe_options(o));
}

}  // namespace mvtwin::forward
