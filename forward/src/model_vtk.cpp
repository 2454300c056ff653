#include "mvtwin/forward/model_vtk.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <set>
#include <sstream>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/vtk_writer.h"
#include "mvtwin/forward/febio_export.h"

namespace mvtwin::forward {

std::vector<std::filesystem::path> export_scene(const ClosureScene& scene,
                                                const ClosureOptions& opt,
                                                const std::filesystem::path& dir,
                                                const std::string& comment,
                                                const std::vector<int>& guarded) {
  const ValveModel& m = scene.model;
  create_output_directory(dir);
  std::vector<std::filesystem::path> out;

  const std::set<int> fixed(m.annulus_nodes.begin(), m.annulus_nodes.end());
  VtkArray prescribed{"prescribed", 1, {}, true};
  for (Eigen::Index i = 0; i < m.linear.V.rows(); ++i)
    prescribed.values.push_back(fixed.count(static_cast<int>(i)) ? 1 : 0);
  write_vtu(dir / "leaflets.vtu", m.linear, {prescribed});
  out.push_back(dir / "leaflets.vtu");

  {
    VtkUnstructuredGrid g;
    g.points = m.mesh.V;
    const int npe = m.mesh.nodes_per_element();
    g.cell_type = npe == 10 ? 24 : 10;
    VtkArray tag{"tag", 1, {}, true}, fibre{"fibre", 3, {}, false};
    for (int e = 0; e < m.mesh.num_elements(); ++e) {
      std::vector<int> c;
      for (int a = 0; a < npe; ++a) c.push_back(m.mesh.T(e, a));
      g.cells.push_back(c);
      tag.values.push_back(m.mesh.tag[e]);
      for (int k = 0; k < 3; ++k) fibre.values.push_back(m.mesh.fibre(e, k));
    }
    VtkArray all_prescribed{"prescribed", 1, std::vector<double>(m.mesh.num_nodes(), 0.0), true};
    for (int i : m.annulus_nodes) all_prescribed.values[i] = 1;
    g.point_data = {all_prescribed};
    g.cell_data = {tag, fibre};
    write_vtu(dir / "leaflets_quadratic.vtu", g);
    out.push_back(dir / "leaflets_quadratic.vtu");
  }

  VtkPolyData ch;
  ch.points.resize(2 * static_cast<Eigen::Index>(scene.chordae.size()), 3);
  VtkArray group{"group", 1, {}, true}, marginal{"marginal", 1, {}, true},
      tip{"papillary_tip", 1, {}, true}, length{"ed_length_mm", 1, {}, false},
      rest{"rest_length_mm", 1, {}, false}, area{"area_mm2", 1, {}, false},
      e_low{"e_low_mpa", 1, {}, false}, e_high{"e_high_mpa", 1, {}, false},
      brk{"strain_break", 1, {}, false};
  for (size_t k = 0; k < scene.chordae.size(); ++k) {
    const SceneChorda& c = scene.chordae[k];
    Eigen::Vector3d ins = Eigen::Vector3d::Zero();
    for (int nd : c.nodes)
      ins += m.mesh.V.row(nd).transpose() / static_cast<double>(c.nodes.size());
    const Eigen::Vector3d t = scene.papillary_tip(c.tip, 0.0);
    ch.points.row(2 * static_cast<Eigen::Index>(k)) = ins.transpose();
    ch.points.row(2 * static_cast<Eigen::Index>(k) + 1) = t.transpose();
    ch.lines.push_back({2 * static_cast<int>(k), 2 * static_cast<int>(k) + 1});
    group.values.push_back(static_cast<int>(c.group));
    marginal.values.push_back(c.marginal);
    tip.values.push_back(c.tip);
    length.values.push_back((ins - t).norm());
    rest.values.push_back(c.rest_length);
    area.values.push_back(c.law.area);
    e_low.values.push_back(c.law.e_low);
    e_high.values.push_back(c.law.e_high);
    brk.values.push_back(c.law.strain_break);
  }
  ch.cell_data = {group, marginal, tip, length, rest, area, e_low, e_high, brk};
  write_vtp(dir / "chordae.vtp", ch);
  out.push_back(dir / "chordae.vtp");

  TriangleMesh ps;
  ps.V = m.linear.V;
  ps.F.resize(static_cast<Eigen::Index>(m.ventricular_faces.size()), 3);
  for (size_t f = 0; f < m.ventricular_faces.size(); ++f)
    ps.F.row(static_cast<Eigen::Index>(f)) = m.ventricular_faces[f].transpose();
  write_vtp(dir / "pressure_surface.vtp", ps);
  out.push_back(dir / "pressure_surface.vtp");

  // Boundary trajectories and the pressure profile, sampled every dt.
  const double T = scene.duration();
  const int samples = std::max(2, static_cast<int>(std::ceil(T / opt.dt - 1e-9)) + 1);
  auto time = [&](int k) { return std::min(T, k * opt.dt); };
  auto header = [&](std::ostringstream& os) {
    std::istringstream lines(comment);
    for (std::string line; std::getline(lines, line);) os << "# " << line << "\n";
  };
  {
    std::ostringstream os;
    header(os);
    os << "# simulated time (s), pressure on the ventricular surface (MPa), papillary tips (mm)\n"
       << "t_s,pressure_mpa,al_tip_x,al_tip_y,al_tip_z,pm_tip_x,pm_tip_y,pm_tip_z\n";
    os.precision(10);
    for (int k = 0; k < samples; ++k) {
      const double t = time(k);
      const Eigen::Vector3d a = scene.papillary_tip(0, t), b = scene.papillary_tip(1, t);
      os << t << "," << scene.pressure(t) << "," << a.x() << "," << a.y() << "," << a.z() << ","
         << b.x() << "," << b.y() << "," << b.z() << "\n";
    }
    write_atomically(dir / "boundary.csv", [&](const std::filesystem::path& tmp) {
      std::ofstream f(tmp);
      f << os.str();
      if (!f) throw Error((dir / "boundary.csv").string() + ": cannot write");
    });
    out.push_back(dir / "boundary.csv");
  }
  {
    std::ostringstream os;
    header(os);
    os << "# simulated time (s), node (0-based, as in leaflets_quadratic.vtu), position (mm)\n"
       << "t_s,node,x,y,z\n";
    os.precision(10);
    std::vector<std::pair<double, std::string>> steps;
    for (int k = 0; k < samples; ++k) {
      const double t = time(k);
      Eigen::VectorXd x = Eigen::VectorXd::Zero(3 * m.mesh.num_nodes());
      scene.prescribed_positions(t, &x);
      for (const PrescribedNode& p : scene.prescribed)
        os << t << "," << p.node << "," << x[3 * p.node] << "," << x[3 * p.node + 1] << ","
           << x[3 * p.node + 2] << "\n";
      // The annulus curve and the tips for ParaView.
      VtkPolyData b;
      const auto a = scene.annulus(t);
      b.points.resize(a.rows() + 2, 3);
      b.points.topRows(a.rows()) = a;
      b.points.row(a.rows()) = scene.papillary_tip(0, t).transpose();
      b.points.row(a.rows() + 1) = scene.papillary_tip(1, t).transpose();
      std::vector<int> loop;
      for (int i = 0; i < a.rows(); ++i) loop.push_back(i);
      loop.push_back(0);
      b.lines.push_back(loop);
      b.verts = {{static_cast<int>(a.rows())}, {static_cast<int>(a.rows()) + 1}};
      char name[64];
      std::snprintf(name, sizeof name, "boundary_%04d.vtp", k);
      write_vtp(dir / name, b);
      out.push_back(dir / name);
      steps.emplace_back(t, name);
    }
    write_pvd(dir / "boundary.pvd", steps);
    out.push_back(dir / "boundary.pvd");
    write_atomically(dir / "annulus_motion.csv", [&](const std::filesystem::path& tmp) {
      std::ofstream f(tmp);
      f << os.str();
      if (!f) throw Error((dir / "annulus_motion.csv").string() + ": cannot write");
    });
    out.push_back(dir / "annulus_motion.csv");
  }
  write_febio(dir / "valve.feb", scene, opt, comment, guarded);
  out.push_back(dir / "valve.feb");
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
