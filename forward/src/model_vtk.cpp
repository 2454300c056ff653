#include "mvtwin/forward/model_vtk.h"

#include <cstdio>
#include <set>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/vtk_writer.h"

namespace mvtwin::forward {

std::vector<std::filesystem::path> export_model_vtk(const ValveModel& m,
                                                    const std::filesystem::path& dir) {
  create_output_directory(dir);
  std::vector<std::filesystem::path> out;

  const std::set<int> fixed(m.annulus_nodes.begin(), m.annulus_nodes.end());
  VtkArray prescribed{"prescribed", 1, {}, true};
  for (Eigen::Index i = 0; i < m.linear.V.rows(); ++i)
    prescribed.values.push_back(fixed.count(static_cast<int>(i)) ? 1 : 0);
  write_vtu(dir / "leaflets.vtu", m.linear, {prescribed});
  out.push_back(dir / "leaflets.vtu");

  VtkPolyData ch;
  ch.points.resize(2 * static_cast<Eigen::Index>(m.chordae.size()), 3);
  VtkArray group{"group", 1, {}, true}, marginal{"marginal", 1, {}, true},
      length{"ed_length_mm", 1, {}, false};
  for (size_t k = 0; k < m.chordae.size(); ++k) {
    const ModelChorda& c = m.chordae[k];
    Eigen::Vector3d ins = Eigen::Vector3d::Zero();
    for (int n : c.nodes) ins += m.mesh.V.row(n).transpose() / static_cast<double>(c.nodes.size());
    ch.points.row(2 * static_cast<Eigen::Index>(k)) = ins.transpose();
    ch.points.row(2 * static_cast<Eigen::Index>(k) + 1) = m.papillary_ed[c.papillary].transpose();
    ch.lines.push_back({2 * static_cast<int>(k), 2 * static_cast<int>(k) + 1});
    group.values.push_back(static_cast<int>(c.group));
    marginal.values.push_back(c.marginal);
    length.values.push_back(c.ed_length);
  }
  ch.cell_data = {group, marginal, length};
  write_vtp(dir / "chordae.vtp", ch);
  out.push_back(dir / "chordae.vtp");

  TriangleMesh ps;
  ps.V = m.linear.V;
  ps.F.resize(static_cast<Eigen::Index>(m.ventricular_faces.size()), 3);
  for (size_t f = 0; f < m.ventricular_faces.size(); ++f)
    ps.F.row(static_cast<Eigen::Index>(f)) = m.ventricular_faces[f].transpose();
  write_vtp(dir / "pressure_surface.vtp", ps);
  out.push_back(dir / "pressure_surface.vtp");
  return out;
}

std::vector<std::filesystem::path> export_closure_vtk(const ClosureResult& r,
                                                      const std::filesystem::path& dir) {
  create_output_directory(dir);
  std::vector<std::filesystem::path> out;
  std::vector<std::pair<double, std::string>> steps;
  for (size_t i = 0; i < r.samples.size(); ++i) {
    char name[64];
    std::snprintf(name, sizeof name, "la_surface_%04zu.vtp", i);
    const LeafletGrid& g = r.samples[i].la_surface;
    const Eigen::VectorXi tags = g.triangle_tags();
    VtkArray tag{"leaflet", 1, std::vector<double>(tags.data(), tags.data() + tags.size()), true};
    write_vtp(dir / name, g.triangulate(), {}, {tag});
    out.push_back(dir / name);
    steps.emplace_back(r.samples[i].time_s, name);
  }
  write_pvd(dir / "simulation.pvd", steps);
  out.push_back(dir / "simulation.pvd");
  if (r.rest_mesh.T.rows() > 0 && r.element_strain.size() == r.rest_mesh.T.rows()) {
    // The end state as a volume mesh with per-element strain and stress.
    TetMesh end = r.rest_mesh;
    for (Eigen::Index i = 0; i < end.V.rows(); ++i)
      end.V.row(i) = r.positions.segment<3>(3 * i).transpose();
    VtkArray strain{"strain_max_principal", 1,
                    std::vector<double>(r.element_strain.data(),
                                        r.element_strain.data() + r.element_strain.size()),
                    false};
    VtkArray stress{"stress_von_mises_MPa", 1,
                    std::vector<double>(r.element_stress_mpa.data(),
                                        r.element_stress_mpa.data() + r.element_stress_mpa.size()),
                    false};
    write_vtu(dir / "leaflets_end.vtu", end, {}, {strain, stress});
    out.push_back(dir / "leaflets_end.vtu");
  }
  return out;
}

}  // namespace mvtwin::forward
