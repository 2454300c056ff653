#include "mvtwin/forward/valve_model.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <map>
#include <string>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "mvtwin/core/error.h"
#include "mvtwin/core/rng.h"
#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/forward/corotational_tet.h"
#include "mvtwin/forward/elastic_body.h"

namespace mvtwin::forward {
namespace {

class ValveModelTest : public ::testing::TestWithParam<std::tuple<int, TetOrder>> {};

TEST_P(ValveModelTest, MeshTagsFibresThickness) {
  const auto [layers, order] = GetParam();
  const Patient p = make_virtual_patient(21);
  ModelOptions o;
  o.ures = 24;
  o.vres = 12;
  o.layers = layers;
  o.order = order;
  const ValveModel m = build_valve_model(p.sequence, o);
  const int N = m.surface_nodes;
  const auto F = m.surface_triangles.rows();
  // 3 tetrahedra per surface triangle and layer; all positive (checked by the builder, again).
  EXPECT_EQ(m.linear.T.rows(), 3 * F * layers);
  EXPECT_EQ(m.linear.V.rows(), static_cast<Eigen::Index>(N) * (layers + 1));
  EXPECT_NO_THROW(m.linear.check("test"));
  EXPECT_EQ(m.mesh.num_elements(), m.linear.T.rows());
  if (order == TetOrder::kQuadratic) {
    EXPECT_GT(m.mesh.num_nodes(), m.linear.V.rows());
  }
  // The atrial surface lies on the end-diastolic surface at its nodes' grid coordinates, and
  // its area equals the grid surface's (the mesh covers the leaflets, no holes, no overlap).
  const LeafletGrid& ed = *p.sequence.frames[p.sequence.end_diastole].la_surface;
  double area = 0.0;
  for (Eigen::Index f = 0; f < F; ++f) {
    const Eigen::Vector3d a = m.mesh.V.row(m.surface_triangles(f, 0)),
                          b = m.mesh.V.row(m.surface_triangles(f, 1)),
                          c = m.mesh.V.row(m.surface_triangles(f, 2));
    area += 0.5 * (b - a).cross(c - a).norm();
  }
  const double grid_area = ed.resampled(96, 60).triangulate().area();
  EXPECT_NEAR(area, grid_area, 0.03 * grid_area);
  for (int i = 0; i < N; i += 7) {
    const Eigen::Vector3d on_grid = ed.sample(m.surface_st(i, 0), m.surface_st(i, 1));
    EXPECT_LT((m.mesh.V.row(m.node(i, 0)).transpose() - on_grid).norm(), 1e-9);
    const double t = (m.mesh.V.row(m.node(i, layers)) - m.mesh.V.row(m.node(i, 0))).norm();
    EXPECT_NEAR(t, m.surface_st(i, 0) < 0.5 ? 1.32 : 1.26, 1e-9);
  }
  // The annulus row is the grid's annulus at columns u = 0..ures-1.
  ASSERT_EQ(m.annulus_column.size(), static_cast<size_t>(o.ures));
  const LeafletGrid g = ed.resampled(o.ures, ed.vres());
  for (int u = 0; u < o.ures; ++u) {
    EXPECT_LT((m.mesh.V.row(m.node(m.annulus_column[u], 0)).transpose() - g.at(u, 0)).norm(), 1e-6);
  }
  // Tags split at s = 1/2; fibres are unit and tangent to the leaflet.
  int anterior = 0;
  for (int e = 0; e < m.mesh.num_elements(); ++e) {
    anterior += m.mesh.tag[e] == static_cast<int>(LeafletTag::kAnterior);
    EXPECT_NEAR(m.mesh.fibre.row(e).norm(), 1.0, 1e-12);
  }
  EXPECT_GT(anterior, m.mesh.num_elements() / 3);
  EXPECT_LT(anterior, 2 * m.mesh.num_elements() / 3);
  // Chordae: 28 marginal on the free edge + 8 basal at mid-leaflet, 4 groups, 4 basal per leaflet.
  int marginal = 0, per_group[4] = {0, 0, 0, 0}, basal_anterior = 0;
  for (const auto& c : m.chordae) {
    marginal += c.marginal;
    per_group[static_cast<int>(c.group)]++;
    if (!c.marginal && c.s < 0.5) ++basal_anterior;
    EXPECT_NEAR(c.t, c.marginal ? 1.0 : 0.5, c.marginal ? 1e-9 : 0.2);
    EXPECT_GT(c.ed_length, 1.0);
  }
  EXPECT_EQ(marginal, 28);
  EXPECT_EQ(m.chordae.size(), 36u);
  EXPECT_EQ(basal_anterior, 4);
  for (int g4 : per_group) EXPECT_GT(g4, 0);
  // Annulus: t = 0 on every layer.
  EXPECT_GE(m.annulus_nodes.size(), static_cast<size_t>(o.ures * (layers + 1)));
  EXPECT_EQ(m.ventricular_faces.size(), static_cast<size_t>(F));
  // The quality report is consistent: in (0, 1] and attained by a real element.
  EXPECT_GT(m.min_quality, 0.0);
  EXPECT_LE(m.min_quality, 1.0);
  EXPECT_GE(m.worst_element, 0);
  EXPECT_LT(m.worst_element, m.mesh.num_elements());
  // The leaflet material builds on this mesh (no inverted element).
  EXPECT_NO_THROW(ElasticBody(m.mesh, [](int tag) {
    return tag == 1 ? TransverselyIsotropic::anterior_leaflet()
                    : TransverselyIsotropic::posterior_leaflet();
  }));
}

// The slivers that stopped the first simulator (quality 1e-4 next to the commissures of the
// (u,v) grid, docs/forward-status.md) are gone on a cohort of every pathology.
TEST(ValveModel, NoSliversOverACohort) {
  double worst = 1.0;
  for (int seed = 300; seed < 320; ++seed) {
    const Patient p = make_virtual_patient(seed);
    for (int ures : {20, 30}) {
      ModelOptions o;
      o.ures = ures;
      o.vres = 30;
      const ValveModel m = build_valve_model(p.sequence, o);
      worst = std::min(worst, m.min_quality);
    }
  }
  std::cout << "worst element quality over 20 patients x ures {20, 30}: " << worst << "\n";
  EXPECT_GT(worst, 0.01);
}

// The virtual patients' closing anatomy folds the commissures at end-diastole (issue 39,
// item 2). Folded tighter than the models can follow, the elements across the fold were slivers
// (worst quality 0.0019 over this cohort and these grids with the first fold rule, which kept
// only the facing columns apart); the generator keeps the fold open enough for the calibration
// grid (20 x 30), the paper's grid and the fine observation model (40 x 40) alike.
TEST(ValveModel, NoSliversWhereTheCommissuresAreFolded) {
  VirtualPatientOptions closing;
  closing.taut_chordae_lengths = true;
  closing.commissure_clearance_mm = 1.0;
  double worst = 1.0;
  for (int seed = 300; seed < 312; ++seed) {
    const Patient p = make_virtual_patient(seed, closing);
    for (int ures : {20, 30, 40}) {
      ModelOptions o;
      o.ures = ures;
      o.vres = ures == 20 ? 30 : ures;
      worst = std::min(worst, build_valve_model(p.sequence, o).min_quality);
    }
  }
  std::cout << "worst element quality over 12 patients x ures {20, 30, 40}: " << worst << "\n";
  EXPECT_GT(worst, 0.01);
}

// Quadratic elements the curved leaflet would fold keep straight edges, and straightening one
// moves mid-edge nodes its neighbours share, which can fold a neighbour already checked. With two
// fixed passes these models of cohort seed 2026 kept folded elements on the widest open frame
// (where the diastole builds its model): patient 0 at 40 x 40 x 3 layers (the fine observation
// model, its element 56 at det J -0.87), patient 18 likewise (its diastole failed at rest, so the
// clip study's true MVA came from the end-diastolic frame), patient 9 at 24 x 24 (the search
// model, 3 elements). The check repeats until nothing is straightened. (Those meshes had
// overlapping triangles, SurfaceTrianglesCoverTheUnrolledLeafletOnce; on the mended ones patients
// 0 and 18 still straighten elements, patient 9 at 24 x 24 none, and patient 21 at 24 x 24 five
// stands in for it.)
TEST(ValveModel, CurvedQuadraticElementsNeverFoldAfterStraightening) {
  struct Case {
    int index, ures, layers;
  };
  for (const Case c : {Case{0, 40, 3}, Case{21, 24, 1}, Case{18, 40, 3}}) {
    Patient p = make_cohort_patient(2026, c.index);
    p.sequence.end_diastole = 0;  // the widest open frame of a virtual patient
    p.sequence.first_closed = 1;
    ModelOptions o;
    o.ures = o.vres = c.ures;
    o.layers = c.layers;
    const ValveModel m = build_valve_model(p.sequence, o);
    int folded = 0;
    for (int e = 0; e < m.mesh.num_elements(); ++e) {
      CorotationalTet<10>::Nodes X;
      for (int a = 0; a < 10; ++a) X.row(a) = m.mesh.V.row(m.mesh.T(e, a));
      folded += CorotationalTet<10>::min_jacobian_of(X) > 0.0 ? 0 : 1;
    }
    EXPECT_EQ(folded, 0) << "patient " << c.index << " at " << c.ures << " x " << c.ures << " x "
                         << c.layers;
    EXPECT_GT(m.straight_elements, 0) << "the case no longer exercises the straightening";
  }
}

// The surface mesh covers the unrolled leaflet once: every edge of the atrial triangles borders
// at most two of them, and in the unrolled plane their areas add up to the leaflet's, the
// integral of the free edge's depth over the annulus. Bowyer-Watson with each circumcircle
// decided on its own overlapped its fans on these near-co-circular lattices: 175 of 250 models
// of cohort seed 2026 (25 patients, 2 frames, 5 grids) covered part of the leaflet twice, by
// up to twice its area (patient 0's widest frame at 40 x 40, a triangle 33 mm across; patient
// 9's end-diastole at 24 x 24, 40 mm), and two left holes.
TEST(ValveModel, SurfaceTrianglesCoverTheUnrolledLeafletOnce) {
  struct Case {
    int index, ures;
    bool widest;
  };
  for (const Case c : {Case{0, 40, true}, Case{9, 24, false}, Case{17, 20, true},
                       Case{8, 20, false}, Case{1, 30, false}}) {
    SCOPED_TRACE("cohort 2026 patient " + std::to_string(c.index) + " at " +
                 std::to_string(c.ures) + (c.widest ? ", widest frame" : ", end-diastole"));
    Patient p = make_cohort_patient(2026, c.index);
    if (c.widest) {
      p.sequence.end_diastole = 0;  // the widest open frame of a virtual patient
      p.sequence.first_closed = 1;
    }
    ModelOptions o;
    o.ures = o.vres = c.ures;
    const ValveModel m = build_valve_model(p.sequence, o);
    std::map<std::pair<int, int>, int> edges, directed;
    double area = 0.0;
    const double P = m.perimeter;
    auto plane = [&](int a, double near_x) {
      Eigen::Vector2d q = m.surface_plane.row(a).transpose();
      q.x() -= P * std::round((q.x() - near_x) / P);
      return q;
    };
    for (Eigen::Index f = 0; f < m.surface_triangles.rows(); ++f) {
      Eigen::Vector2d q[3];
      for (int k = 0; k < 3; ++k) {
        const int a = m.surface_triangles(f, k), b = m.surface_triangles(f, (k + 1) % 3);
        ++edges[{std::min(a, b), std::max(a, b)}];
        ++directed[{a, b}];
        q[k] = plane(a, m.surface_plane(m.surface_triangles(f, 0), 0));
      }
      area += 0.5 * std::abs((q[1] - q[0]).x() * (q[2] - q[0]).y() -
                             (q[1] - q[0]).y() * (q[2] - q[0]).x());
    }
    int over = 0;
    for (const auto& [e, n] : edges) over += n > 2 ? 1 : 0;
    EXPECT_EQ(over, 0) << "edges bordering more than two triangles";
    // The leaflet's area in the plane from its boundary (the directed edges without a reverse):
    // the trapezoids under them add up to the area between the annulus (depth 0, adding
    // nothing) and the free edge.
    double leaflet = 0.0;
    for (const auto& [e, n] : directed) {
      if (directed.count({e.second, e.first})) continue;
      const Eigen::Vector2d a = plane(e.first, 0.0), b = plane(e.second, a.x());
      leaflet += 0.5 * (b.x() - a.x()) * (a.y() + b.y());
    }
    EXPECT_NEAR(area, std::abs(leaflet), 1e-6 * area);
  }
}

// A refinement region makes the lattice denser there and only there: the surface nodes inside
// it grow about factor^2-fold, those far from it stay, and the elements keep their quality.
TEST(ValveModel, RefinementRegionIsDenserThereAndOnlyThere) {
  double worst = 1.0;
  for (int seed = 330; seed < 335; ++seed) {
    const Patient p = make_virtual_patient(seed);
    ModelOptions o;
    const ValveModel plain = build_valve_model(p.sequence, o);
    o.refine_factor = 3;
    o.refine_regions = {{0.25, 6.0, 8.0}, {0.75, 6.0, 6.0}};
    const ValveModel fine = build_valve_model(p.sequence, o);
    worst = std::min(worst, fine.min_quality);
    // Nodes within a region's core (1 mm inside its border) and beyond 2 coarse steps of both.
    auto count = [&](const ValveModel& m, bool inside) {
      int n = 0;
      const double hx = m.perimeter / o.ures;
      for (int i = 0; i < m.surface_nodes; ++i) {
        const double t = m.surface_st(i, 1);
        if (t <= 0.0) continue;
        const double depth = m.surface_plane(i, 1), from_edge = depth * (1.0 / t - 1.0);
        bool in_core = false, near = false;
        for (const auto& r : o.refine_regions) {
          // The site's arc length: the annulus columns' unrolled positions, interpolated.
          const double x = r.s * o.ures;
          const int u0 = static_cast<int>(std::floor(x)) % o.ures, u1 = (u0 + 1) % o.ures;
          const double xi0 = m.surface_plane(m.annulus_column[static_cast<size_t>(u0)], 0);
          double xi1 = m.surface_plane(m.annulus_column[static_cast<size_t>(u1)], 0);
          if (xi1 < xi0) xi1 += m.perimeter;
          const double xi = xi0 + (x - std::floor(x)) * (xi1 - xi0);
          double d = m.surface_plane(i, 0) - xi;
          d -= m.perimeter * std::round(d / m.perimeter);
          in_core =
              in_core || (std::abs(d) < r.half_width_mm - 1.0 && from_edge < r.from_edge_mm - 1.0);
          near = near || std::abs(d) < r.half_width_mm + 2 * hx;
        }
        if (inside ? in_core : !near) ++n;
      }
      return n;
    };
    EXPECT_GT(count(fine, true), 5 * count(plain, true)) << "seed " << seed;
    EXPECT_NEAR(count(fine, false), count(plain, false), 0.05 * count(plain, false))
        << "seed " << seed;
  }
  EXPECT_GT(worst, 0.01);
  ModelOptions bad;
  bad.refine_factor = 9;
  std::string why;
  EXPECT_FALSE(bad.is_valid(&why));
  EXPECT_NE(why.find("refine_factor"), std::string::npos);
}

TEST(ValveModel, AtrialSamplerReproducesTheSurface) {
  const Patient p = make_virtual_patient(24);
  const ValveModel m = build_valve_model(p.sequence);
  const LeafletGrid& ed = *p.sequence.frames[p.sequence.end_diastole].la_surface;
  const AtrialSampler s = make_atrial_sampler(m, 30, 30);
  Eigen::VectorXd x(3 * m.mesh.num_nodes());
  for (int i = 0; i < m.mesh.num_nodes(); ++i) x.segment<3>(3 * i) = m.mesh.V.row(i).transpose();
  const LeafletGrid g = sample_atrial(s, x);
  // Piecewise-linear interpolation of a curved surface: close to the grid, exact at the annulus.
  double worst = 0.0, mean = 0.0;
  for (int v = 0; v < 30; ++v) {
    for (int u = 0; u < 30; ++u) {
      const double d = (g.at(u, v) - ed.sample(u / 30.0, v / 29.0)).norm();
      worst = std::max(worst, d);
      mean += d / 900.0;
      if (v == 0) {
        EXPECT_LT(d, 1e-6);
      }
    }
  }
  std::cout << "sampler vs grid: mean " << mean << " mm, max " << worst << " mm\n";
  EXPECT_LT(mean, 0.1);
  EXPECT_LT(worst, 1.0);
}

INSTANTIATE_TEST_SUITE_P(LayersAndOrder, ValveModelTest,
                         ::testing::Combine(::testing::Values(1, 3),
                                            ::testing::Values(TetOrder::kLinear,
                                                              TetOrder::kQuadratic)));

TEST(ValveModel, FibresCircumferentialTurningRadialAtAnteriorCommissures) {
  const Patient p = make_virtual_patient(22);
  const ValveModel m = build_valve_model(p.sequence);
  const LeafletGrid& ed = *p.sequence.frames[p.sequence.end_diastole].la_surface;
  // Mean |cos| between the fibre and the circumferential direction of the grid over the
  // elements whose centroid lies in a band of s (mid-leaflet depth).
  auto alignment = [&](double s0, double s1) {
    double sum = 0.0;
    int n = 0;
    for (Eigen::Index e = 0; e < m.linear.T.rows(); e += 3) {
      Eigen::Vector2d st = Eigen::Vector2d::Zero();
      const int a = m.linear.T(e, 0) % m.surface_nodes;
      for (int k = 0; k < 4; ++k) {
        Eigen::Vector2d q = m.surface_st.row(m.linear.T(e, k) % m.surface_nodes).transpose();
        q.x() -= std::round(q.x() - m.surface_st(a, 0));
        st += q / 4.0;
      }
      st.x() -= std::floor(st.x());
      if (st.x() < s0 || st.x() >= s1 || st.y() < 0.3 || st.y() > 0.7) continue;
      // Circumferential: along the line of constant depth (mm from the annulus), with the
      // radial part removed.
      const double depth = st.y() * ed.radial_length_at(st.x());
      auto at_depth = [&](double s) {
        return ed.sample(s, std::min(1.0, depth / ed.radial_length_at(s)));
      };
      const Eigen::Vector3d radial =
          (ed.sample(st.x(), st.y() + 1e-3) - ed.sample(st.x(), st.y() - 1e-3)).normalized();
      Eigen::Vector3d around = at_depth(st.x() + 1e-3) - at_depth(st.x() - 1e-3);
      around = (around - radial * radial.dot(around)).normalized();
      sum += std::abs(m.linear.fibre.row(e).dot(around.transpose()));
      ++n;
    }
    EXPECT_GT(n, 0);
    return sum / n;
  };
  // Mid-posterior and mid-anterior: circumferential.
  EXPECT_GT(alignment(0.70, 0.80), 0.95);
  EXPECT_GT(alignment(0.20, 0.30), 0.95);
  // Next to the anterior commissures: more radial than circumferential, turning gradually back.
  const double c0 = alignment(0.0, 0.03), c1 = alignment(0.05, 0.09), c2 = alignment(0.12, 0.16);
  // (c1 and c2 are compared with a numerical circumferential direction that differs from the
  // builder's by up to ~15 degrees in the curved commissural region.)
  EXPECT_LT(c0, 0.5);
  EXPECT_LT(c0 + 0.3, c1);
  EXPECT_GT(c2, 0.9);
  EXPECT_LT(alignment(0.47, 0.5), 0.5);  // the other commissure
  // Posterior next to the commissure stays circumferential.
  EXPECT_GT(alignment(0.52, 0.6), 0.9);
}

// Detection-like noise on every grid point (0.3-1 mm) used to fail the builder ("degenerate
// leaflet surface"). Clean grids are left alone; noisy ones are smoothed until their
// roughness is below the threshold's half, build valid elements, and stay close to the clean
// surface.
TEST(ValveModel, NoisyInputIsSmoothedCleanInputIsNot) {
  ModelOptions o;
  o.ures = 20;
  o.vres = 10;
  for (int seed : {1, 2, 3, 4, 5}) {
    const Patient p = make_virtual_patient(static_cast<std::uint64_t>(seed));
    const ValveModel clean = build_valve_model(p.sequence, o);
    EXPECT_LT(clean.input_roughness_mm, 0.5 * o.smoothing_roughness_mm) << "seed " << seed;
    EXPECT_EQ(clean.smoothing_passes, 0);
    for (double sd : {0.3, 0.6, 1.0}) {
      Patient q = p;
      Rng rng(static_cast<std::uint64_t>(100 * seed) + static_cast<std::uint64_t>(10 * sd));
      auto& P = q.sequence.frames[q.sequence.end_diastole].la_surface->points();
      const int U = q.sequence.frames[q.sequence.end_diastole].la_surface->ures();
      for (Eigen::Index k = U; k < P.rows(); ++k)
        for (int c = 0; c < 3; ++c) P(k, c) += rng.normal(0.0, sd);
      ValveModel noisy;
      ASSERT_NO_THROW(noisy = build_valve_model(q.sequence, o)) << "seed " << seed << " sd " << sd;
      EXPECT_GT(noisy.input_roughness_mm, o.smoothing_roughness_mm);
      EXPECT_GT(noisy.smoothing_passes, 0);
      EXPECT_GT(noisy.min_quality, 0.005) << "seed " << seed << " sd " << sd;
      // The smoothed model's atrial surface against the clean one (same grid sampling).
      const AtrialSampler sc = make_atrial_sampler(clean, 20, 10),
                          sn = make_atrial_sampler(noisy, 20, 10);
      Eigen::VectorXd xc(3 * clean.mesh.num_nodes()), xn(3 * noisy.mesh.num_nodes());
      for (int i = 0; i < clean.mesh.num_nodes(); ++i)
        xc.segment<3>(3 * i) = clean.mesh.V.row(i).transpose();
      for (int i = 0; i < noisy.mesh.num_nodes(); ++i)
        xn.segment<3>(3 * i) = noisy.mesh.V.row(i).transpose();
      const LeafletGrid gc = sample_atrial(sc, xc), gn = sample_atrial(sn, xn);
      const double mean = (gc.points() - gn.points()).rowwise().norm().mean();
      EXPECT_LT(mean, std::max(0.6, 0.9 * sd)) << "seed " << seed << " sd " << sd;
    }
  }
}

TEST(ValveModel, SharpCommissuresLeaveNoNodeWithoutAnElement) {
  // Detected valves can have shorter leaflets at the commissures than the generator's (the demo
  // patient's detection: 6.9 mm against 10.1 at the anterolateral commissure). Each column is
  // shortened towards the annulus by the ratio that detection showed, fading away from the
  // commissures; the mesh must keep every node in an element.
  const std::array<double, 5> ratio = {0.68, 0.77, 0.86, 0.91, 0.95};
  ModelOptions o;  // the calibration default, 30 x 30
  int checked = 0;
  for (int seed : {1, 2, 3, 4, 5, 6}) {
    Patient p = make_virtual_patient(static_cast<std::uint64_t>(seed));
    LeafletGrid& g =
        *p.sequence.frames[static_cast<std::size_t>(p.sequence.end_diastole)].la_surface;
    const int U = g.ures(), V = g.vres();
    for (int u = 0; u < U; ++u) {
      const int d = std::min({u, std::abs(u - U / 2), U - u});  // columns from a commissure
      if (d >= static_cast<int>(ratio.size())) continue;
      const Eigen::Vector3d a = g.at(u, 0);
      for (int v = 1; v < V; ++v)
        g.points().row(v * U + u) =
            (a + ratio[static_cast<std::size_t>(d)] * (g.at(u, v) - a)).transpose();
    }
    ValveModel m;
    ASSERT_NO_THROW(m = build_valve_model(p.sequence, o)) << "seed " << seed;
    std::vector<int> uses(static_cast<std::size_t>(m.surface_nodes), 0);
    for (Eigen::Index t = 0; t < m.surface_triangles.rows(); ++t)
      for (int k = 0; k < 3; ++k) ++uses[static_cast<std::size_t>(m.surface_triangles(t, k))];
    EXPECT_EQ(std::count(uses.begin(), uses.end(), 0), 0) << "seed " << seed;
    EXPECT_GT(m.min_quality, 0.005) << "seed " << seed;
    ++checked;
  }
  EXPECT_EQ(checked, 6);
}

TEST(ValveModel, BadInputIsNamed) {
  Patient p = make_virtual_patient(23);
  ModelOptions o;
  o.layers = 0;
  EXPECT_THROW(build_valve_model(p.sequence, o), Error);
  p.sequence.end_diastole = -1;
  try {
    build_valve_model(p.sequence);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no end-diastolic frame"), std::string::npos);
  }
}

}  // namespace
}  // namespace mvtwin::forward
