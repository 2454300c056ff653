#include <Eigen/Geometry>

#include "mvtwin/core/patient_vtk.h"

#include <cstdio>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/vtk_writer.h"

namespace mvtwin {

std::vector<std::filesystem::path> export_patient_vtk(const Patient& patient,
                                                      const std::filesystem::path& dir) {
  create_output_directory(dir);
  const ValveSequence& seq = patient.sequence;
  std::vector<std::filesystem::path> written;
  std::vector<std::pair<double, std::string>> surf_steps, ann_steps, lm_steps;
  for (int f = 0; f < seq.num_frames(); ++f) {
    const ValveFrame& fr = seq.frames[f];
    char name[64];

    std::snprintf(name, sizeof name, "la_surface_%04d.vtp", f);
    if (fr.la_surface) {
      const LeafletGrid& g = *fr.la_surface;
      VtkArray u{"u", 1, {}, true}, v{"v", 1, {}, true}, tag{"leaflet", 1, {}, true};
      for (int j = 0; j < g.vres(); ++j) {
        for (int i = 0; i < g.ures(); ++i) {
          u.values.push_back(i);
          v.values.push_back(j);
        }
      }
      const Eigen::VectorXi tags = g.triangle_tags();
      tag.values.assign(tags.data(), tags.data() + tags.size());
      write_vtp(dir / name, g.triangulate(), {u, v}, {tag});
    } else {
      write_vtp(dir / name, VtkPolyData{});  // leaflets not observed in this frame
    }
    written.push_back(dir / name);
    surf_steps.emplace_back(fr.time_s, name);

    std::snprintf(name, sizeof name, "annulus_%04d.vtp", f);
    VtkPolyData ann;
    ann.points = fr.annulus;
    std::vector<int> loop;
    for (int i = 0; i < seq.ures; ++i) loop.push_back(i);
    loop.push_back(0);
    ann.lines.push_back(loop);
    VtkArray u{"u", 1, {}, true};
    for (int i = 0; i < seq.ures; ++i) u.values.push_back(i);
    ann.point_data.push_back(u);
    write_vtp(dir / name, ann);
    written.push_back(dir / name);
    ann_steps.emplace_back(fr.time_s, name);

    std::snprintf(name, sizeof name, "landmarks_%04d.vtp", f);
    VtkPolyData lm;
    std::vector<Eigen::Vector3d> pts;
    VtkArray id{"landmark", 1, {}, true};
    for (int l = 0; l < kNumLandmarks; ++l) {
      if (!fr.landmark_observed[l]) continue;
      lm.verts.push_back({static_cast<int>(pts.size())});
      pts.push_back(fr.landmarks[l]);
      id.values.push_back(l);
    }
    lm.points.resize(static_cast<Eigen::Index>(pts.size()), 3);
    for (size_t i = 0; i < pts.size(); ++i)
      lm.points.row(static_cast<Eigen::Index>(i)) = pts[i].transpose();
    lm.point_data.push_back(id);
    write_vtp(dir / name, lm);
    written.push_back(dir / name);
    lm_steps.emplace_back(fr.time_s, name);
  }
  write_pvd(dir / "la_surface.pvd", surf_steps);
  write_pvd(dir / "annulus.pvd", ann_steps);
  write_pvd(dir / "landmarks.pvd", lm_steps);
  for (const char* n : {"la_surface.pvd", "annulus.pvd", "landmarks.pvd"})
    written.push_back(dir / n);
  return written;
}

}  // namespace mvtwin
