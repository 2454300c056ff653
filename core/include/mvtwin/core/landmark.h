#pragma once
#include <array>
#include <string_view>

namespace mvtwin {

/// The nine anatomical landmarks of the paper (Mansi et al. 2012, Sec. 2.1), in storage order.
/// "Anterolateral" is the patient's left side (the left fibrous trigone, the anterior
/// commissure, the anterolateral papillary muscle).
enum class Landmark : int {
  kAnterolateralTrigone = 0,
  kPosteromedialTrigone = 1,
  kPosteriorAnnulusMidpoint = 2,
  kAnterolateralCommissure = 3,
  kPosteromedialCommissure = 4,
  kAnteriorLeafletTip = 5,
  kPosteriorLeafletTip = 6,
  kAnterolateralPapillaryTip = 7,
  kPosteromedialPapillaryTip = 8,
};

inline constexpr int kNumLandmarks = 9;

inline constexpr std::array<std::string_view, kNumLandmarks> kLandmarkNames = {
    "anterolateral_trigone",    "posteromedial_trigone",       "posterior_annulus_midpoint",
    "anterolateral_commissure", "posteromedial_commissure",    "anterior_leaflet_tip",
    "posterior_leaflet_tip",    "anterolateral_papillary_tip", "posteromedial_papillary_tip"};

constexpr int index(Landmark l) { return static_cast<int>(l); }
constexpr std::string_view name(Landmark l) { return kLandmarkNames[static_cast<int>(l)]; }

}  // namespace mvtwin
