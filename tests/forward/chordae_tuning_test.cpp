#include "mvtwin/forward/chordae_tuning.h"

#include <cmath>

#include <gtest/gtest.h>

#include "mvtwin/core/error.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/forward/virtual_closure.h"

namespace mvtwin::forward {
namespace {

/// The paper's 28 marginal insertion sites, each chorda 20 mm.
std::vector<ChordaLength> sites28() {
  std::vector<ChordaLength> l;
  for (int k = 0; k < 28; ++k) l.push_back({k / 28.0, 20.0});
  return l;
}

/// A closed valve's orifice with one column: its leaflet, position along the line, gap, and
/// the other leaflet's closest point `rise` mm along the atrial normal (z) from it.
RegurgitantOrifice one_column(bool anterior, double position, double gap_mm, double rise) {
  RegurgitantOrifice o;
  o.options.seal_mm = 0.6;
  ColumnGap c;
  c.anterior = anterior;
  c.position = position;
  c.gap_mm = gap_mm;
  c.a = Eigen::Vector3d(1, 2, -8);
  c.b = c.a + Eigen::Vector3d(0.3, 0, rise);
  o.columns.push_back(c);
  return o;
}

const Eigen::Vector3d kAtrial(0, 0, 1);

TEST(ChordaeTuning, AnOpenColumnMovesItsOwnLeafletsChordaeByATentOverTheSites) {
  const ChordaeTuningOptions o;  // gain 1, reach 2.5 sites, at most 3 mm counted
  // Anterior column at 0.4 of the line: insertion site s = 0.2 (site 5.6 of 28). The posterior
  // leaflet lies 1 mm above it: the anterior leaflet must rise, its chordae lengthen by
  // gap - seal = 1.0 mm times the tent 1 - |site - 5.6| / 2.5.
  const std::vector<double> d =
      chordae_length_changes(one_column(true, 0.4, 1.6, 1.0), sites28(), kAtrial, o);
  ASSERT_EQ(d.size(), 28u);
  for (int k = 0; k < 28; ++k) {
    const double ds = std::abs(k - 5.6);
    const double expect = ds < 2.5 ? 1.0 * (1.0 - ds / 2.5) : 0.0;
    EXPECT_NEAR(d[k], expect, 1e-12) << "site " << k;
  }
  EXPECT_GT(d[6], d[4]);
  // The other leaflet below: shorten by the same amounts.
  const std::vector<double> down =
      chordae_length_changes(one_column(true, 0.4, 1.6, -1.0), sites28(), kAtrial, o);
  for (int k = 0; k < 28; ++k) EXPECT_NEAR(down[k], -d[k], 1e-12) << "site " << k;
  // A wide gap counts at most max_step_mm above the seal.
  const std::vector<double> wide =
      chordae_length_changes(one_column(true, 0.4, 10.0, 1.0), sites28(), kAtrial, o);
  EXPECT_NEAR(wide[6], 3.0 * d[6], 1e-12);
  // A sealed column (gap within the seal) moves nothing.
  for (double x : chordae_length_changes(one_column(true, 0.4, 0.6, 1.0), sites28(), kAtrial, o))
    EXPECT_EQ(x, 0.0);
}

TEST(ChordaeTuning, APosteriorColumnMovesOnlyPosteriorChordaeAndCommissuresBelongToBoth) {
  const ChordaeTuningOptions o;
  // Posterior column at 0.4: site s = 1 - 0.2 = 0.8 (22.4 of 28).
  const std::vector<double> d =
      chordae_length_changes(one_column(false, 0.4, 1.6, 1.0), sites28(), kAtrial, o);
  for (int k = 0; k < 28; ++k) {
    const double ds = std::abs(k - 22.4);
    EXPECT_NEAR(d[k], ds < 2.5 ? 1.0 - ds / 2.5 : 0.0, 1e-12) << "site " << k;
  }
  // An anterior column beside the anterolateral commissure (0.02 of the line: s = 0.01) moves
  // the commissural chorda (s = 0) and its anterior neighbours, not the posterior site 27
  // although it is as near around the annulus.
  const std::vector<double> c =
      chordae_length_changes(one_column(true, 0.02, 1.6, 1.0), sites28(), kAtrial, o);
  EXPECT_GT(c[0], 0.0);
  EXPECT_GT(c[1], 0.0);
  EXPECT_EQ(c[27], 0.0);
  // The same column on the posterior leaflet: site 27 and the commissure, not site 1.
  const std::vector<double> p =
      chordae_length_changes(one_column(false, 0.02, 1.6, 1.0), sites28(), kAtrial, o);
  EXPECT_GT(p[0], 0.0);
  EXPECT_GT(p[27], 0.0);
  EXPECT_EQ(p[1], 0.0);
}

TEST(ChordaeTuning, ANormalValvesOrificeShrinksAndTheKeptLengthsReproduceIt) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "four closures take minutes under AddressSanitizer";
#endif
  // Cohort seed 2026's patient 0 (normal) leaks 10 mm^2 on a coarse model.
  const Patient p = make_cohort_patient(2026, 0);
  ASSERT_EQ(p.truth->pathology, Pathology::kNormal);
  ASSERT_TRUE(is_tunable_normal_valve(p));
  EXPECT_EQ(tuning_edition(p), 0);
  ChordaeTuningOptions o;
  o.simulation.model.ures = 20;
  o.simulation.model.vres = 10;
  o.simulation.threads = 1;
  o.iterations = 2;
  Patient tuned_patient = p;
  const ChordaeTuning t = tune_normal_virtual_patient(&tuned_patient, o);
  ASSERT_EQ(t.eroa_mm2.size(), 3u) << t.failure;
  EXPECT_TRUE(t.failure.empty()) << t.failure;
  EXPECT_GT(t.eroa_mm2[0], 5.0) << "the untuned valve should leak on this model";
  EXPECT_LT(t.eroa_mm2[t.best], 0.6 * t.eroa_mm2[0]);
  for (double e : t.eroa_mm2) EXPECT_GE(e, t.eroa_mm2[t.best]);
  // The patient carries the kept lengths and says how they were made.
  EXPECT_EQ(tuning_edition(tuned_patient), kChordaeTuningEdition);
  double recorded = -1;
  for (const auto& [name, value] : tuned_patient.truth->anatomy)
    if (name == "chordae_tuning_eroa_mm2") recorded = value;
  EXPECT_EQ(recorded, t.eroa_mm2[t.best]);
  EXPECT_NE(tuned_patient.provenance.source.find("tuned to close"), std::string::npos);
  // Lengths moved, each within [shortest, longest] x its own, at the same sites.
  const auto& start = p.sequence.marginal_chordae_lengths;
  ASSERT_EQ(t.lengths.size(), start.size());
  ASSERT_EQ(tuned_patient.sequence.marginal_chordae_lengths.size(), start.size());
  double moved = 0;
  for (size_t j = 0; j < start.size(); ++j) {
    EXPECT_EQ(t.lengths[j].s, start[j].s);
    EXPECT_EQ(tuned_patient.sequence.marginal_chordae_lengths[j].length_mm, t.lengths[j].length_mm);
    EXPECT_GE(t.lengths[j].length_mm, o.shortest * start[j].length_mm - 1e-12);
    EXPECT_LE(t.lengths[j].length_mm, o.longest * start[j].length_mm + 1e-12);
    moved += std::abs(t.lengths[j].length_mm - start[j].length_mm);
  }
  EXPECT_GT(moved, 1.0);
  // The kept lengths are the ones that closure was made with.
  ValveSequence tuned = p.sequence;
  tuned.marginal_chordae_lengths = t.lengths;
  const ClosureResult r = simulate_closure(tuned, p.truth->parameters, o.simulation);
  ASSERT_TRUE(r.summary.converged()) << r.summary.reason;
  ASSERT_TRUE(r.orifice.has_value());
  EXPECT_DOUBLE_EQ(r.orifice->eroa_mm2, t.eroa_mm2[t.best]);
}

TEST(ChordaeTuning, OnlyNormalVirtualValvesAreTunedAndNothingIsChangedWhenRefused) {
  Patient sick = make_cohort_patient(2026, 2);  // ruptured chordae
  ASSERT_NE(sick.truth->pathology, Pathology::kNormal);
  EXPECT_FALSE(is_tunable_normal_valve(sick));
  const auto before = sick.sequence.marginal_chordae_lengths;
  try {
    tune_normal_virtual_patient(&sick);
    ADD_FAILURE() << "a sick valve: expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("leak is its pathology"), std::string::npos) << e.what();
  }
  ASSERT_EQ(sick.sequence.marginal_chordae_lengths.size(), before.size());
  for (size_t j = 0; j < before.size(); ++j)
    EXPECT_EQ(sick.sequence.marginal_chordae_lengths[j].length_mm, before[j].length_mm);
  Patient real = make_cohort_patient(2026, 0);
  real.synthetic = false;
  EXPECT_FALSE(is_tunable_normal_valve(real));
  EXPECT_THROW(tune_normal_virtual_patient(&real), Error);
  // A tuning made before editions were recorded counts as edition 1.
  Patient old = make_cohort_patient(2026, 0);
  old.truth->anatomy.emplace_back("chordae_tuning_eroa_mm2", 1.0);
  EXPECT_EQ(tuning_edition(old), 1);
}

TEST(ChordaeTuning, AnObservedNormalValveIsTunedFirstAndASickOneIsNot) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "four closures take minutes under AddressSanitizer";
#endif
  VirtualClosureOptions v;
  v.simulation = ClosureOptions{};
  v.simulation.model.ures = 16;
  v.simulation.model.vres = 8;
  v.simulation.threads = 1;
  v.noise_mm = 0;
  v.tune_normal_chordae = true;
  v.tuning.simulation = v.simulation;  // as the test above: 10 mm^2 shrinks on 20 x 10
  v.tuning.simulation.model.ures = 20;
  v.tuning.simulation.model.vres = 10;
  v.tuning.iterations = 2;
  Patient normal = make_cohort_patient(2026, 0);
  const auto start = normal.sequence.marginal_chordae_lengths;
  simulate_observed_closure(&normal, v);
  EXPECT_EQ(tuning_edition(normal), kChordaeTuningEdition);
  ASSERT_EQ(normal.sequence.marginal_chordae_lengths.size(), start.size());
  double moved = 0;
  for (size_t j = 0; j < start.size(); ++j)
    moved += std::abs(normal.sequence.marginal_chordae_lengths[j].length_mm - start[j].length_mm);
  EXPECT_GT(moved, 0.5);
  ASSERT_TRUE(normal.truth->closed_orifice.has_value());
  Patient sick = make_cohort_patient(2026, 1);
  const auto sick_start = sick.sequence.marginal_chordae_lengths;
  simulate_observed_closure(&sick, v);
  EXPECT_EQ(tuning_edition(sick), 0);
  for (size_t j = 0; j < sick_start.size(); ++j)
    EXPECT_EQ(sick.sequence.marginal_chordae_lengths[j].length_mm, sick_start[j].length_mm);
}

TEST(ChordaeTuning, AValveWithoutChordaeLengthsAndBadOptionsAreRefused) {
  const Patient plain = make_virtual_patient(1, VirtualPatientOptions::before_closing_anatomy());
  ASSERT_TRUE(plain.sequence.marginal_chordae_lengths.empty());
  try {
    tune_marginal_chordae(plain.sequence, plain.truth->parameters);
    ADD_FAILURE() << "no chordae lengths: expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("marginal chordae lengths"), std::string::npos)
        << e.what();
  }
  const Patient p = make_virtual_patient(1);
  for (auto bad : {+[](ChordaeTuningOptions* o) { o->iterations = -1; },
                   +[](ChordaeTuningOptions* o) { o->gain = 0; },
                   +[](ChordaeTuningOptions* o) { o->shortest = 1.2; },
                   +[](ChordaeTuningOptions* o) { o->longest = std::nan(""); },
                   +[](ChordaeTuningOptions* o) { o->reach_sites = 0; }}) {
    ChordaeTuningOptions o;
    bad(&o);
    EXPECT_FALSE(o.problem().empty());
    EXPECT_THROW(tune_marginal_chordae(p.sequence, p.truth->parameters, o), Error);
  }
}

}  // namespace
}  // namespace mvtwin::forward
