#include "mvtwin/inverse/parameter_space.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "mvtwin/core/error.h"
#include "mvtwin/core/units.h"

namespace mvtwin::inverse {

const std::vector<ParameterSpec>& parameter_catalogue() {
  static const std::vector<ParameterSpec> catalogue = [] {
    std::vector<ParameterSpec> c;
    // Bounds cover the virtual cohort's pathologies (elongated chordae up to 1.5,
    // docs/virtual-patients.md) with room; the scales are the size of a change that moves the
    // closed valve visibly.
    for (int g = 0; g < kNumChordaeGroups; ++g) {
      c.push_back({"restlength_factor_" + std::string(kChordaeGroupNames[g]), "restlength", "1",
                   0.7, 1.6, 1.0, 0.05, 1.0});
    }
    c.push_back({"marginal_stiffness_scale", "stiffness", "1", 0.2, 5.0, 1.0, 0.2, 1.0});
    c.push_back({"basal_stiffness_scale", "stiffness", "1", 0.2, 5.0, 1.0, 0.2, 1.0});
    c.push_back(
        {"peak_pressure", "pressure", "mmHg", 60.0, 200.0, 120.0, 10.0, units::mmhg_to_mpa(1.0)});
    c.push_back({"al_modulus_scale", "modulus", "1", 0.2, 6.0, 1.0, 0.2, 1.0});
    c.push_back({"pl_modulus_scale", "modulus", "1", 0.2, 6.0, 1.0, 0.2, 1.0});
    return c;
  }();
  return catalogue;
}

namespace {

double* member(ValveParameters& p, const std::string& name) {
  double* out = nullptr;
  p.for_each([&](const std::string& n, double& v, const char*) {
    if (n == name) out = &v;
  });
  if (!out) throw Error("parameter space: ValveParameters has no '" + name + "'");
  return out;
}

}  // namespace

ParameterSpace::ParameterSpace(const std::string& selection, const ValveParameters& base)
    : base_(base) {
  std::vector<bool> chosen(parameter_catalogue().size(), false);
  std::stringstream ss(selection);
  std::string item;
  while (std::getline(ss, item, ',')) {
    item.erase(0, item.find_first_not_of(" \t"));
    item.erase(item.find_last_not_of(" \t") + 1);
    if (item.empty()) continue;
    bool found = false;
    for (size_t i = 0; i < parameter_catalogue().size(); ++i) {
      const ParameterSpec& s = parameter_catalogue()[i];
      if (s.group == item || s.name == item) chosen[i] = found = true;
    }
    if (!found) {
      std::string known = "restlength, stiffness, pressure, modulus";
      for (const auto& s : parameter_catalogue()) known += ", " + s.name;
      throw Error("parameter space: unknown parameter or group '" + item + "' (known: " + known +
                  ")");
    }
  }
  for (size_t i = 0; i < chosen.size(); ++i)
    if (chosen[i]) specs_.push_back(parameter_catalogue()[i]);
  if (specs_.empty()) throw Error("parameter space: nothing chosen to fit ('" + selection + "')");
}

Eigen::VectorXd ParameterSpace::values_of(const ValveParameters& p) const {
  ValveParameters q = p;
  Eigen::VectorXd x(size());
  for (int i = 0; i < size(); ++i) x[i] = *member(q, specs_[i].name) / specs_[i].to_internal;
  return x;
}

ValveParameters ParameterSpace::apply(const Eigen::VectorXd& x) const {
  if (x.size() != size()) throw Error("parameter space: wrong number of values");
  ValveParameters p = base_;
  for (int i = 0; i < size(); ++i) {
    const ParameterSpec& s = specs_[i];
    const double tol = 1e-9 * (s.upper - s.lower);
    if (!std::isfinite(x[i]) || x[i] < s.lower - tol || x[i] > s.upper + tol) {
      std::ostringstream os;
      os << "parameter space: " << s.name << " = " << x[i] << " " << s.unit << " is outside ["
         << s.lower << ", " << s.upper << "]";
      throw Error(os.str());
    }
    *member(p, s.name) = std::clamp(x[i], s.lower, s.upper) * s.to_internal;
  }
  return p;
}

Eigen::VectorXd ParameterSpace::lower() const {
  Eigen::VectorXd v(size());
  for (int i = 0; i < size(); ++i) v[i] = specs_[i].lower;
  return v;
}
Eigen::VectorXd ParameterSpace::upper() const {
  Eigen::VectorXd v(size());
  for (int i = 0; i < size(); ++i) v[i] = specs_[i].upper;
  return v;
}
Eigen::VectorXd ParameterSpace::scales() const {
  Eigen::VectorXd v(size());
  for (int i = 0; i < size(); ++i) v[i] = specs_[i].scale;
  return v;
}
Eigen::VectorXd ParameterSpace::start() const {
  return values_of(base_).cwiseMax(lower()).cwiseMin(upper());
}
std::string ParameterSpace::names() const {
  std::string out;
  for (const auto& s : specs_) out += (out.empty() ? "" : ",") + s.name;
  return out;
}

}  // namespace mvtwin::inverse
