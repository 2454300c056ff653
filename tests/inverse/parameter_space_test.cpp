#include "mvtwin/inverse/parameter_space.h"

#include <gtest/gtest.h>

#include "mvtwin/core/error.h"
#include "mvtwin/core/units.h"

namespace mvtwin::inverse {
namespace {

TEST(ParameterSpace, GroupsAndNamesSelectInCatalogueOrder) {
  const ParameterSpace s("pressure, restlength", ValveParameters{});
  ASSERT_EQ(s.size(), 5);
  EXPECT_EQ(s.specs()[0].name, "restlength_factor_" + std::string(kChordaeGroupNames[0]));
  EXPECT_EQ(s.specs()[4].name, "peak_pressure");
  EXPECT_EQ(s.specs()[4].unit, "mmHg");
  const ParameterSpace t("basal_stiffness_scale,stiffness", ValveParameters{});
  EXPECT_EQ(t.size(), 2) << "a parameter named twice is chosen once";
  EXPECT_EQ(ParameterSpace("restlength,stiffness,pressure,modulus", ValveParameters{}).size(),
            static_cast<int>(parameter_catalogue().size()));
}

TEST(ParameterSpace, UnknownOrEmptySelectionIsNamed) {
  try {
    ParameterSpace("restlength,stifness", ValveParameters{});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'stifness'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ParameterSpace(" , ", ValveParameters{}), Error);
}

TEST(ParameterSpace, ApplyWritesUserUnitsIntoTheBaseAndReadsThemBack) {
  ValveParameters base;
  base.al_modulus_scale = 2.5;  // not fitted: must survive
  const ParameterSpace s("restlength,pressure", base);
  Eigen::VectorXd x(5);
  x << 1.1, 0.9, 1.3, 0.8, 100.0;
  const ValveParameters p = s.apply(x);
  EXPECT_DOUBLE_EQ(p.restlength_factor[2], 1.3);
  EXPECT_NEAR(p.peak_pressure_mpa, units::mmhg_to_mpa(100.0), 1e-15);
  EXPECT_DOUBLE_EQ(p.al_modulus_scale, 2.5);
  EXPECT_LT((s.values_of(p) - x).norm(), 1e-12);
  EXPECT_NEAR(s.start()[4], 120.0, 1e-9) << "the default pressure, in mmHg";
}

TEST(ParameterSpace, OutOfBoundsOrNonFiniteValuesAreRefused) {
  const ParameterSpace s("stiffness", ValveParameters{});
  Eigen::VectorXd x(2);
  x << 1.0, 100.0;
  EXPECT_THROW(s.apply(x), Error);
  x << std::nan(""), 1.0;
  EXPECT_THROW(s.apply(x), Error);
  EXPECT_THROW(s.apply(Eigen::VectorXd::Ones(3)), Error);
  ValveParameters wild;
  wild.marginal_stiffness_scale = 50.0;
  EXPECT_DOUBLE_EQ(ParameterSpace("stiffness", wild).start()[0], s.upper()[0])
      << "the start point is clamped into the bounds";
}

}  // namespace
}  // namespace mvtwin::inverse
