#pragma once
#include <array>
#include <string>
#include <string_view>

#include "mvtwin/core/units.h"

namespace mvtwin {

/// Chordae groups for personalization (Mansi et al. 2012, Sec. 2.2): papillary side x
/// marginal/basal.
enum class ChordaeGroup : int {
  kAnterolateralMarginal = 0,
  kAnterolateralBasal = 1,
  kPosteromedialMarginal = 2,
  kPosteromedialBasal = 3,
};
inline constexpr int kNumChordaeGroups = 4;
inline constexpr std::array<std::string_view, kNumChordaeGroups> kChordaeGroupNames = {
    "anterolateral_marginal", "anterolateral_basal", "posteromedial_marginal",
    "posteromedial_basal"};

/// The patient-specific parameters that calibration fits (issue 4) and that a virtual patient
/// hides. Defaults are the paper's generic values (Mansi et al. 2012, Table 1).
struct ValveParameters {
  /// Chordae rest length = end-diastolic insertion-to-tip distance times this factor, per
  /// ChordaeGroup.
  std::array<double, kNumChordaeGroups> restlength_factor{1.0, 1.0, 1.0, 1.0};
  /// Multipliers of the marginal and basal chordae Young's moduli (both slopes of the law).
  double marginal_stiffness_scale = 1.0;
  double basal_stiffness_scale = 1.0;
  /// Multipliers of all anterior / posterior leaflet moduli.
  double al_modulus_scale = 1.0;
  double pl_modulus_scale = 1.0;
  /// Peak transvalvular pressure in MPa (paper: 120 mmHg).
  double peak_pressure_mpa = units::mmhg_to_mpa(120.0);

  /// Visits every scalar as f(name, value, unit) in a fixed order (files and reports).
  template <typename F>
  void for_each(F&& f) {
    visit(*this, f);
  }
  template <typename F>
  void for_each(F&& f) const {
    visit(*this, f);
  }

 private:
  template <typename Self, typename F>
  static void visit(Self& p, F& f) {
    for (int g = 0; g < kNumChordaeGroups; ++g) {
      f("restlength_factor_" + std::string(kChordaeGroupNames[g]), p.restlength_factor[g], "1");
    }
    f(std::string("marginal_stiffness_scale"), p.marginal_stiffness_scale, "1");
    f(std::string("basal_stiffness_scale"), p.basal_stiffness_scale, "1");
    f(std::string("al_modulus_scale"), p.al_modulus_scale, "1");
    f(std::string("pl_modulus_scale"), p.pl_modulus_scale, "1");
    f(std::string("peak_pressure"), p.peak_pressure_mpa, units::kStress);
  }
};

}  // namespace mvtwin
