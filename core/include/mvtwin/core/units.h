#pragma once
// mvtwin's internal unit system: length mm, time s, force N, stress MPa (N/mm^2),
// mass tonne (t = 1e3 kg), so that N = t*mm/s^2 and density is in t/mm^3.
// Values from papers and users are converted here, at the edges, and nowhere else.

namespace mvtwin::units {

/// Standard gravity in m/s^2 (defines gram-force; CGPM 1901).
inline constexpr double kStandardGravity_m_s2 = 9.80665;
/// One mmHg in Pa (conventional millimetre of mercury, 133.322387415 Pa).
inline constexpr double kPaPerMmHg = 133.322387415;

// ---- pressure / stress (internal: MPa) -----------------------------------------------------
constexpr double mmhg_to_mpa(double mmhg) { return mmhg * kPaPerMmHg * 1e-6; }
constexpr double mpa_to_mmhg(double mpa) { return mpa / (kPaPerMmHg * 1e-6); }
constexpr double kpa_to_mpa(double kpa) { return kpa * 1e-3; }
constexpr double pa_to_mpa(double pa) { return pa * 1e-6; }
/// gram-force per mm^2 -> MPa: 1 gf/mm^2 = 9.80665e-3 N/mm^2.
constexpr double gf_per_mm2_to_mpa(double v) { return v * kStandardGravity_m_s2 * 1e-3; }

// ---- force and stiffness (internal: N, N/mm) ------------------------------------------------
/// gram-force -> N: 1 gf = 1e-3 kg * 9.80665 m/s^2.
constexpr double gf_to_n(double gf) { return gf * kStandardGravity_m_s2 * 1e-3; }
/// gram-force per mm -> N/mm.
constexpr double gf_per_mm_to_n_per_mm(double v) { return gf_to_n(v); }

// ---- density / mass (internal: t/mm^3, t) ---------------------------------------------------
/// g/mL = g/cm^3 -> t/mm^3: 1 g/cm^3 = 1e-6 t / 1e3 mm^3 = 1e-9 t/mm^3.
constexpr double g_per_ml_to_t_per_mm3(double v) { return v * 1e-9; }
constexpr double kg_to_t(double kg) { return kg * 1e-3; }

// ---- length, area, time ---------------------------------------------------------------------
constexpr double m_to_mm(double m) { return m * 1e3; }
constexpr double cm_to_mm(double cm) { return cm * 10.0; }
constexpr double cm2_to_mm2(double cm2) { return cm2 * 100.0; }
constexpr double mm2_to_cm2(double mm2) { return mm2 / 100.0; }
constexpr double ms_to_s(double ms) { return ms * 1e-3; }

/// Names of the internal units, written as attributes into every file.
inline constexpr const char* kLength = "mm";
inline constexpr const char* kTime = "s";
inline constexpr const char* kForce = "N";
inline constexpr const char* kStress = "MPa";
inline constexpr const char* kMass = "t";

}  // namespace mvtwin::units
