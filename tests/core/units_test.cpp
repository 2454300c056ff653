#include "mvtwin/core/units.h"

#include <gtest/gtest.h>

namespace mvtwin::units {
namespace {

// Every conversion against an independently stated reference value.
TEST(Units, PressureFromMmHg) {
  // 120 mmHg = 15998.7 Pa = 0.0159987 MPa (Mansi et al. 2012, Sec. 2.3: 120 mmHg = 0.016 MPa).
  EXPECT_NEAR(mmhg_to_mpa(120.0), 0.0159987, 1e-7);
  EXPECT_NEAR(mpa_to_mmhg(mmhg_to_mpa(87.5)), 87.5, 1e-12);
  EXPECT_DOUBLE_EQ(kpa_to_mpa(16.0), 0.016);
  EXPECT_DOUBLE_EQ(pa_to_mpa(1e6), 1.0);
}

TEST(Units, GramForceToSi) {
  // Mansi et al. 2012, Sec. 2.3: marginal chordae 312 / 3406 gf/mm^2 = 3.06 / 33.4 MPa; basal 66 /
  // 2120 gf/mm^2 = 0.647 / 20.8 MPa; k_clip 1000 gf/mm = 9.81 N/mm.
  EXPECT_NEAR(gf_per_mm2_to_mpa(312.0), 3.06, 0.005);
  EXPECT_NEAR(gf_per_mm2_to_mpa(3406.0), 33.4, 0.05);
  EXPECT_NEAR(gf_per_mm2_to_mpa(66.0), 0.647, 0.001);
  EXPECT_NEAR(gf_per_mm2_to_mpa(2120.0), 20.8, 0.05);
  EXPECT_NEAR(gf_per_mm_to_n_per_mm(1000.0), 9.81, 0.005);  // 1000 gf/mm with g = 9.80665 m/s^2
  EXPECT_DOUBLE_EQ(gf_to_n(1.0), 9.80665e-3);
}

TEST(Units, DensityAndMass) {
  // 1.04 g/mL = 1040 kg/m^3 = 1.04e-9 t/mm^3 (Mansi et al. 2012, Sec. 2.3).
  EXPECT_DOUBLE_EQ(g_per_ml_to_t_per_mm3(1.04), 1.04e-9);
  EXPECT_DOUBLE_EQ(kg_to_t(1000.0), 1.0);
  // Consistency of the system: 1 t * 1 mm/s^2 = 1 N  (1000 kg * 1e-3 m/s^2).
  EXPECT_DOUBLE_EQ(kg_to_t(1000.0) * 1.0, 1.0);
}

TEST(Units, LengthAreaTime) {
  EXPECT_DOUBLE_EQ(m_to_mm(0.03), 30.0);
  EXPECT_DOUBLE_EQ(cm_to_mm(2.5), 25.0);
  EXPECT_DOUBLE_EQ(cm2_to_mm2(7.7), 770.0);
  EXPECT_DOUBLE_EQ(mm2_to_cm2(980.0), 9.8);
  EXPECT_DOUBLE_EQ(ms_to_s(40.0), 0.04);
}

}  // namespace
}  // namespace mvtwin::units
