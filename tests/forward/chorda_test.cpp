#include "mvtwin/forward/chorda.h"

#include <gtest/gtest.h>

#include "mvtwin/core/units.h"

namespace mvtwin::forward {
namespace {

TEST(ChordaLaw, PaperValuesInInternalUnits) {
  const ChordaLaw m = ChordaLaw::marginal(), b = ChordaLaw::basal();
  EXPECT_NEAR(m.e_low, 3.06, 0.005);  // Mansi et al. 2012, Sec. 2.3
  EXPECT_NEAR(m.e_high, 33.4, 0.05);
  EXPECT_NEAR(b.e_low, 0.647, 0.001);
  EXPECT_NEAR(b.e_high, 20.8, 0.05);
}

TEST(ChordaLaw, TensionOnlyAndContinuousAtTheBreakpoint) {
  const ChordaLaw m = ChordaLaw::marginal();
  EXPECT_EQ(m.stress(-0.1), 0.0);
  EXPECT_EQ(m.stress(0.0), 0.0);
  const double eb = m.strain_break;
  EXPECT_NEAR(m.stress(eb - 1e-12), m.stress(eb + 1e-12), 1e-9);
  EXPECT_NEAR(m.stress(eb + 0.01), m.e_low * eb + m.e_high * 0.01, 1e-12);
  // Energy density is the integral of the stress.
  for (double e : {-0.05, 0.01, 0.03, 0.08}) {
    const double h = 1e-7;
    EXPECT_NEAR((m.energy_density(e + h) - m.energy_density(e - h)) / (2 * h), m.stress(e), 1e-6);
  }
}

TEST(Chorda, ForceAndStiffnessMatchFiniteDifferences) {
  const ChordaLaw law = ChordaLaw::basal();
  const double L0 = 10.0;
  const Eigen::Vector3d a(0.3, -0.2, 0.1);
  for (double stretch : {1.02, 1.08}) {  // both branches of the law, away from the kinks
    const Eigen::Vector3d b = a + stretch * L0 * Eigen::Vector3d(0.6, 0.0, 0.8);
    Eigen::Matrix<double, 6, 1> g;
    Eigen::Matrix<double, 6, 6> H;
    double E = 0;
    chorda_gradient(law, L0, a, b, &g, &H, &E);
    EXPECT_GT(E, 0.0);
    const double h = 1e-6;
    for (int j = 0; j < 6; ++j) {
      Eigen::Vector3d ap = a, am = a, bp = b, bm = b;
      (j < 3 ? ap : bp)[j % 3] += h;
      (j < 3 ? am : bm)[j % 3] -= h;
      Eigen::Matrix<double, 6, 1> gp, gm;
      double Ep = 0, Em = 0;
      chorda_gradient(law, L0, ap, bp, &gp, nullptr, &Ep);
      chorda_gradient(law, L0, am, bm, &gm, nullptr, &Em);
      EXPECT_NEAR((Ep - Em) / (2 * h), g[j], 1e-6 * (1 + g.norm()));  // g = dE/dx
      EXPECT_LT(((gp - gm) / (2 * h) - H.col(j)).norm(), 1e-5 * (1 + H.norm()));
    }
    // Equal and opposite forces along the chorda; the pull on b points back to a.
    EXPECT_LT((g.head<3>() + g.tail<3>()).norm(), 1e-12);
    EXPECT_GT(g.tail<3>().dot(b - a), 0.0);
  }
  // Slack: nothing.
  Eigen::Matrix<double, 6, 1> g;
  Eigen::Matrix<double, 6, 6> H;
  chorda_gradient(law, L0, a, a + Eigen::Vector3d(0, 0, 9.0), &g, &H);
  EXPECT_EQ(g.norm(), 0.0);
  EXPECT_EQ(H.norm(), 0.0);
}

}  // namespace
}  // namespace mvtwin::forward
