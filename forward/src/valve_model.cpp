#include "mvtwin/forward/valve_model.h"

#include <cmath>
#include <numbers>
#include <set>

#include <Eigen/Geometry>

#include "mvtwin/core/error.h"

namespace mvtwin::forward {
namespace {

using std::numbers::pi;

// Fibre angle from circumferential, by leaflet and position: circumferential everywhere except
// near the commissures of the anterior leaflet, where it turns gradually to radial
// (Mansi et al. 2012, Fig. 5, after May-Newman and Yin 1995).
double fibre_angle(bool anterior, double s_in_leaflet) {
  if (!anterior) return 0.0;
  const double from_commissure = std::min(s_in_leaflet, 1.0 - s_in_leaflet);
  const double w = std::max(0.0, 1.0 - from_commissure / 0.25);
  return 0.5 * pi * w * w;
}

}  // namespace

bool ModelOptions::is_valid(std::string* error) const {
  if (ures < 8 || ures % 2) {
    *error = "ures must be even and >= 8";
    return false;
  }
  if (vres < 4) {
    *error = "vres must be >= 4";
    return false;
  }
  if (layers < 1 || layers > 8) {
    *error = "layers must be in 1..8";
    return false;
  }
  if (marginal_chordae < 4 || marginal_chordae > 4 * ures) {
    *error = "marginal_chordae must be in 4..4*ures";
    return false;
  }
  if (!(al_thickness_mm > 0.1 && al_thickness_mm < 5 && pl_thickness_mm > 0.1 &&
        pl_thickness_mm < 5)) {
    *error = "leaflet thickness must be in (0.1, 5) mm";
    return false;
  }
  return true;
}

int ValveModel::node(int u, int v, int layer) const {
  const int U = options.ures, V = options.vres;
  u = ((u % U) + U) % U;
  return (layer * V + v) * U + u;
}

ValveModel build_valve_model(const ValveSequence& seq, const ModelOptions& opt) {
  std::string err;
  if (!opt.is_valid(&err)) throw Error("valve model: " + err);
  if (seq.end_diastole < 0) throw Error("valve model: the sequence has no end-diastolic frame");
  const ValveFrame& ed = seq.frames.at(seq.end_diastole);
  if (!ed.la_surface) throw Error("valve model: leaflets are not observed at end-diastole");
  for (Landmark l : {Landmark::kAnterolateralPapillaryTip, Landmark::kPosteromedialPapillaryTip}) {
    if (!ed.observed(l)) {
      throw Error("valve model: " + std::string(name(l)) + " is not observed at end-diastole");
    }
  }
  ValveModel m;
  m.options = opt;
  m.papillary_ed[0] = ed.landmark(Landmark::kAnterolateralPapillaryTip);
  m.papillary_ed[1] = ed.landmark(Landmark::kPosteromedialPapillaryTip);
  const int U = opt.ures, V = opt.vres, L = opt.layers;
  const LeafletGrid grid = ed.la_surface->resampled(U, V);

  // Vertex normals of the atrial surface, towards the ventricle (the grid's triangle winding).
  const TriangleMesh tri = grid.triangulate();
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> normal =
      Eigen::MatrixXd::Zero(U * V, 3);
  for (Eigen::Index f = 0; f < tri.F.rows(); ++f) {
    const Eigen::Vector3d a = tri.V.row(tri.F(f, 0)), b = tri.V.row(tri.F(f, 1)),
                          c = tri.V.row(tri.F(f, 2));
    const Eigen::Vector3d n = (b - a).cross(c - a);  // area-weighted
    for (int k = 0; k < 3; ++k) normal.row(tri.F(f, k)) += n.transpose();
  }
  for (int i = 0; i < U * V; ++i) {
    const double len = normal.row(i).norm();
    if (!(len > 0))
      throw Error("valve model: degenerate leaflet surface at grid point " + std::to_string(i));
    normal.row(i) /= len;
  }
  auto thickness = [&](int u) {
    // Blend the two thicknesses over the commissure columns.
    return grid.column_tag(u) == LeafletTag::kAnterior ? opt.al_thickness_mm : opt.pl_thickness_mm;
  };

  // Corner nodes: (layer, v, u).
  TetMesh& lin = m.linear;
  lin.V.resize(static_cast<Eigen::Index>(L + 1) * V * U, 3);
  for (int l = 0; l <= L; ++l) {
    for (int v = 0; v < V; ++v) {
      for (int u = 0; u < U; ++u) {
        const int id = (l * V + v) * U + u;
        lin.V.row(id) = grid.at(u, v).transpose() +
                        (static_cast<double>(l) / L) * thickness(u) * normal.row(v * U + u);
      }
    }
  }
  // Hexahedral cells (u, v, layer) -> 6 Kuhn tetrahedra each (conforming, u wraps).
  const int paths[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  std::vector<Eigen::Vector4i> tets;
  std::vector<int> tags;
  std::vector<Eigen::Vector3d> fibres;
  for (int l = 0; l < L; ++l) {
    for (int v = 0; v + 1 < V; ++v) {
      for (int u = 0; u < U; ++u) {
        const bool anterior = grid.column_tag(u) == LeafletTag::kAnterior;
        // Fibre of the cell: circumferential (along u) turned towards radial (along v).
        const Eigen::Vector3d p00 = grid.at(u, v), p10 = grid.at(u + 1, v), p01 = grid.at(u, v + 1),
                              p11 = grid.at(u + 1, v + 1);
        Eigen::Vector3d tu = (p10 + p11 - p00 - p01).normalized();
        Eigen::Vector3d tv = (p01 + p11 - p00 - p10);
        tv = (tv - tu * tu.dot(tv)).normalized();
        const double s = anterior ? (u + 0.5) / (U / 2) : (u + 0.5 - U / 2) / (U / 2);
        const double angle = fibre_angle(anterior, s);
        const Eigen::Vector3d fibre = std::cos(angle) * tu + std::sin(angle) * tv;
        for (const auto& p : paths) {
          int c[3] = {u, v, l};
          Eigen::Vector4i t;
          t[0] = m.node(c[0], c[1], c[2]);
          for (int k = 0; k < 3; ++k) {
            ++c[p[k]];
            t[k + 1] = m.node(c[0], c[1], c[2]);
          }
          const Eigen::Vector3d a = lin.V.row(t[0]), b = lin.V.row(t[1]), cc = lin.V.row(t[2]),
                                d = lin.V.row(t[3]);
          if ((b - a).cross(cc - a).dot(d - a) < 0) std::swap(t[1], t[2]);
          tets.push_back(t);
          tags.push_back(
              static_cast<int>(anterior ? LeafletTag::kAnterior : LeafletTag::kPosterior));
          fibres.push_back(fibre);
        }
      }
    }
  }
  lin.T.resize(static_cast<Eigen::Index>(tets.size()), 4);
  lin.tag.resize(static_cast<Eigen::Index>(tets.size()));
  lin.fibre.resize(static_cast<Eigen::Index>(tets.size()), 3);
  for (size_t e = 0; e < tets.size(); ++e) {
    lin.T.row(static_cast<Eigen::Index>(e)) = tets[e].transpose();
    lin.tag[static_cast<Eigen::Index>(e)] = tags[e];
    lin.fibre.row(static_cast<Eigen::Index>(e)) = fibres[e].transpose();
  }
  lin.check("valve model");  // throws for an element inverted by the extrusion
  m.min_quality = 1.0;
  for (Eigen::Index e = 0; e < lin.T.rows(); ++e) {
    double longest = 0.0;
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j)
        longest = std::max(longest, (lin.V.row(lin.T(e, i)) - lin.V.row(lin.T(e, j))).norm());
    }
    const double q =
        6.0 * std::sqrt(2.0) * lin.volume(static_cast<int>(e)) / (longest * longest * longest);
    if (q < m.min_quality) {
      m.min_quality = q;
      m.worst_element = static_cast<int>(e);
    }
  }
  m.mesh = make_solid(lin, opt.order);

  // Prescribed: the annulus row on every layer (and the mid-edge nodes between those).
  std::set<int> ann;
  for (int l = 0; l <= L; ++l) {
    for (int u = 0; u < U; ++u) ann.insert(m.node(u, 0, l));
  }
  if (opt.order == TetOrder::kQuadratic) {
    for (const auto& [edge, mid] : m.mesh.mid_edge) {
      if (ann.count(edge.first) && ann.count(edge.second)) ann.insert(mid);
    }
  }
  m.annulus_nodes.assign(ann.begin(), ann.end());

  // Pressure acts on the ventricular surface (layer L), triangles facing the ventricle.
  for (int v = 0; v + 1 < V; ++v) {
    for (int u = 0; u < U; ++u) {
      const int a = m.node(u, v, L), b = m.node(u + 1, v, L), c = m.node(u + 1, v + 1, L),
                d = m.node(u, v + 1, L);
      m.ventricular_faces.emplace_back(a, b, c);
      m.ventricular_faces.emplace_back(a, c, d);
    }
  }

  // Chordae (SPEC Sec. 3) on the ventricular surface; each to the tip on its side.
  auto add = [&](double u_site, int v, bool marginal) {
    const int u = static_cast<int>(std::lround(u_site)) % U;
    const double s = static_cast<double>(u) / U;
    const bool anterolateral = s < 0.25 || s >= 0.75;
    ModelChorda c;
    c.node = m.node(u, v, L);
    c.papillary = anterolateral ? 0 : 1;
    c.marginal = marginal;
    c.group = static_cast<ChordaeGroup>((anterolateral ? 0 : 2) + (marginal ? 0 : 1));
    c.u = u;
    c.v = v;
    for (int l = 0; l <= L; ++l) {
      c.nodes.push_back(m.node(u, v, l));
      if (l > 0 && opt.order == TetOrder::kQuadratic) {
        const int mid = m.mesh.mid_node(m.node(u, v, l - 1), m.node(u, v, l));
        if (mid >= 0) c.nodes.push_back(mid);
      }
    }
    Eigen::Vector3d insertion = Eigen::Vector3d::Zero();
    for (int k : c.nodes) insertion += m.mesh.V.row(k).transpose();
    insertion /= static_cast<double>(c.nodes.size());
    c.ed_length = (insertion - m.papillary_ed[c.papillary]).norm();
    m.chordae.push_back(c);
  };
  for (int k = 0; k < opt.marginal_chordae; ++k)
    add(static_cast<double>(k) * U / opt.marginal_chordae, V - 1, true);
  const int v_basal = (V - 1) / 2;
  for (int i = 0; i < 4; ++i) {
    const double site = (2 * i + 1) * U / 8.0;
    add(site, v_basal, false);
    add(site + 1, v_basal, false);
  }
  return m;
}

}  // namespace mvtwin::forward
