#include "mvtwin/forward/valve_model.h"

#include <cmath>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "mvtwin/core/error.h"
#include "mvtwin/core/virtual_patient.h"
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
  // 6 tetrahedra per grid cell and layer; all positive (checked by the builder, again here).
  EXPECT_EQ(m.linear.T.rows(), 6 * o.ures * (o.vres - 1) * layers);
  EXPECT_NO_THROW(m.linear.check("test"));
  EXPECT_EQ(m.mesh.num_elements(), m.linear.T.rows());
  if (order == TetOrder::kQuadratic) {
    EXPECT_GT(m.mesh.num_nodes(), m.linear.V.rows());
  }
  // The atrial surface is the (resampled) end-diastolic grid; thickness as prescribed.
  const LeafletGrid g =
      p.sequence.frames[p.sequence.end_diastole].la_surface->resampled(o.ures, o.vres);
  for (int u = 0; u < o.ures; u += 5) {
    EXPECT_LT((m.mesh.V.row(m.node(u, 3, 0)).transpose() - g.at(u, 3)).norm(), 1e-12);
    const double t = (m.mesh.V.row(m.node(u, 3, layers)) - m.mesh.V.row(m.node(u, 3, 0))).norm();
    EXPECT_NEAR(t, u < o.ures / 2 ? 1.32 : 1.26, 1e-9);
  }
  // Tags split at ures/2; fibres are unit and tangent to the leaflet.
  int anterior = 0;
  for (int e = 0; e < m.mesh.num_elements(); ++e) {
    anterior += m.mesh.tag[e] == static_cast<int>(LeafletTag::kAnterior);
    EXPECT_NEAR(m.mesh.fibre.row(e).norm(), 1.0, 1e-12);
  }
  EXPECT_EQ(anterior, m.mesh.num_elements() / 2);
  // Chordae: 28 marginal + 8 basal, 4 groups, basal 4 per leaflet and 2 per papillary tip-site.
  int marginal = 0, per_group[4] = {0, 0, 0, 0}, basal_anterior = 0;
  for (const auto& c : m.chordae) {
    marginal += c.marginal;
    per_group[static_cast<int>(c.group)]++;
    if (!c.marginal && c.u < o.ures / 2) ++basal_anterior;
    EXPECT_GT(c.ed_length, 1.0);
  }
  EXPECT_EQ(marginal, 28);
  EXPECT_EQ(m.chordae.size(), 36u);
  EXPECT_EQ(basal_anterior, 4);
  for (int g4 : per_group) EXPECT_GT(g4, 0);
  // Annulus: v = 0 on every layer.
  EXPECT_GE(m.annulus_nodes.size(), static_cast<size_t>(o.ures * (layers + 1)));
  EXPECT_EQ(m.ventricular_faces.size(), static_cast<size_t>(2 * o.ures * (o.vres - 1)));
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

INSTANTIATE_TEST_SUITE_P(LayersAndOrder, ValveModelTest,
                         ::testing::Combine(::testing::Values(1, 3),
                                            ::testing::Values(TetOrder::kLinear,
                                                              TetOrder::kQuadratic)));

TEST(ValveModel, FibresCircumferentialTurningRadialAtAnteriorCommissures) {
  const Patient p = make_virtual_patient(22);
  const ValveModel m = build_valve_model(p.sequence);
  const int U = m.options.ures, V = m.options.vres;
  auto cell_fibre = [&](int u, int v) {
    // first element of cell (u, v, layer 0)
    return Eigen::Vector3d(m.mesh.fibre.row(6 * (v * U + u)).transpose());
  };
  auto along_u = [&](int u, int v) {
    return Eigen::Vector3d((m.mesh.V.row(m.node(u + 1, v, 0)) - m.mesh.V.row(m.node(u, v, 0)))
                               .normalized()
                               .transpose());
  };
  // Mid-posterior and mid-anterior: circumferential.
  EXPECT_GT(std::abs(cell_fibre(3 * U / 4, V / 2).dot(along_u(3 * U / 4, V / 2))), 0.95);
  EXPECT_GT(std::abs(cell_fibre(U / 4, V / 2).dot(along_u(U / 4, V / 2))), 0.95);
  // Next to an anterior commissure: more radial than circumferential (68 degrees at the first
  // cell centre), turning gradually back to circumferential.
  const double c0 = std::abs(cell_fibre(0, V / 2).dot(along_u(0, V / 2)));
  const double c2 = std::abs(cell_fibre(2, V / 2).dot(along_u(2, V / 2)));
  const double c5 = std::abs(cell_fibre(5, V / 2).dot(along_u(5, V / 2)));
  EXPECT_LT(c0, 0.45);
  EXPECT_LT(c0, c2);
  EXPECT_LT(c2, c5);
  EXPECT_GT(c5, 0.95);
  EXPECT_LT(std::abs(cell_fibre(U / 2 - 1, V / 2).dot(along_u(U / 2 - 1, V / 2))),
            0.45);  // other commissure
  // Posterior next to the commissure stays circumferential.
  EXPECT_GT(std::abs(cell_fibre(U - 1, V / 2).dot(along_u(U - 1, V / 2))), 0.9);
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
