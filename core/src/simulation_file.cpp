#include "mvtwin/core/simulation_file.h"

#include "hdf5_io.h"
#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/units.h"
#include "mvtwin/core/version.h"
#include "orifice_io.h"
#include "result_header.h"

namespace mvtwin {
namespace {

constexpr const char* kFormat = "mvtwin-simulation";
constexpr long kFormatVersion = 1;

std::vector<double> flat(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& m) {
  return std::vector<double>(m.data(), m.data() + m.size());
}

}  // namespace

void write_simulation_file(const std::filesystem::path& path, const SimulationRecord& r) {
  const size_t S = r.time_s.size();
  for (const auto* v : {&r.observed_time_s, &r.anterior_tip_mm, &r.posterior_tip_mm,
                        &r.orifice_area_mm2, &r.annulus_area_mm2}) {
    if (v->size() != S) throw Error(path.string() + ": time series of different lengths");
  }
  if (r.la_surface.size() != S) throw Error(path.string() + ": one surface per sample needed");
  if (S == 0) throw Error(path.string() + ": no recorded sample");
  const int U = r.la_surface[0].ures(), V = r.la_surface[0].vres();
  const auto E = static_cast<hsize_t>(r.mesh.T.rows());
  const auto N = static_cast<hsize_t>(r.mesh.V.rows());
  if (r.final_positions.rows() != r.mesh.V.rows() ||
      r.element_strain.size() != static_cast<Eigen::Index>(E) ||
      r.element_stress_mpa.size() != static_cast<Eigen::Index>(E)) {
    throw Error(path.string() + ": final state sizes do not match the mesh");
  }
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    h5::Location root = h5::Location::create_file(tmp);
    h5::write_result_header(root, kFormat, kFormatVersion, "simulation",
                            {r.patient_id, r.patient_file, r.synthetic, r.provenance, r.options});
    root.attr("status", r.status);
    root.attr("reason", r.reason);
    root.attr("outcome", r.outcome);
    root.attr("units_length", std::string(units::kLength));
    root.attr("units_time", std::string(units::kTime));
    root.attr("units_stress", std::string(units::kStress));

    const h5::Location par = root.create_group("parameters", true);
    r.parameters.for_each(
        [&](const std::string& n, double v, const char* unit) { par.write_scalar(n, v, unit); });
    const h5::Location sum = root.create_group("summary", true);
    for (const auto& [k, v] : r.summary) sum.write_scalar(k, v, nullptr);
    if (!r.static_residual_n.empty()) {
      const h5::Location st = root.create_group("static_solve");
      st.attr("description", std::string("the static equilibrium solve at peak pressure: the force "
                                         "residual at its start and after each Newton iteration"));
      st.attr("failure", r.static_failure);
      st.write("residual_n", r.static_residual_n, {r.static_residual_n.size()}, "N");
    }

    const h5::Location ts = root.create_group("samples");
    ts.attr("ures", static_cast<long>(U));
    ts.attr("vres", static_cast<long>(V));
    ts.attr("description", std::string("recorded states; la_surface is [sample][v][u][xyz] on the "
                                       "patient grid convention; the last sample is the end"));
    ts.write("time_s", r.time_s, {S}, "s (simulated, stretched)");
    ts.write("observed_time_s", r.observed_time_s, {S}, "s (image sequence clock)");
    ts.write("anterior_tip_to_annulus_plane_mm", r.anterior_tip_mm, {S}, "mm, + atrial");
    ts.write("posterior_tip_to_annulus_plane_mm", r.posterior_tip_mm, {S}, "mm, + atrial");
    ts.write("orifice_area_mm2", r.orifice_area_mm2, {S}, "mm^2");
    ts.write("annulus_area_mm2", r.annulus_area_mm2, {S}, "mm^2");
    std::vector<double> la;
    la.reserve(S * static_cast<size_t>(U * V * 3));
    for (const LeafletGrid& g : r.la_surface) {
      if (g.ures() != U || g.vres() != V)
        throw Error(path.string() + ": surfaces on different grids");
      const auto f = flat(g.points());
      la.insert(la.end(), f.begin(), f.end());
    }
    ts.write("la_surface", la, {S, static_cast<hsize_t>(V), static_cast<hsize_t>(U), 3}, "mm");

    const h5::Location fin = root.create_group("final");
    fin.attr("description",
             std::string("linear (corner) tetrahedral mesh: rest_positions, final_positions, "
                         "tets (0-based), tag (1 anterior, 2 posterior), fibre; per element the "
                         "largest principal co-rotational strain and the von Mises stress"));
    fin.write("rest_positions", flat(r.mesh.V), {N, 3}, "mm");
    fin.write("final_positions", flat(r.final_positions), {N, 3}, "mm");
    std::vector<int> tets(r.mesh.T.data(), r.mesh.T.data() + r.mesh.T.size());
    fin.write("tets", tets, {E, 4});
    std::vector<int> tag(r.mesh.tag.data(), r.mesh.tag.data() + r.mesh.tag.size());
    fin.write("tag", tag, {E});
    fin.write("fibre", flat(r.mesh.fibre), {E, 3}, "1");
    fin.write("strain_max_principal",
              std::vector<double>(r.element_strain.data(), r.element_strain.data() + E), {E}, "1");
    fin.write("stress_von_mises",
              std::vector<double>(r.element_stress_mpa.data(), r.element_stress_mpa.data() + E),
              {E}, units::kStress);
    if (r.orifice) h5::write_orifice(root, *r.orifice, &r.orifice_surface, &r.orifice_lv_surface);
  });
}

SimulationRecord read_simulation_file(const std::filesystem::path& path) {
  const h5::Location root = h5::Location::open_file(path);
  h5::ResultHeader h = h5::read_result_header(root, kFormat, kFormatVersion, "simulation");
  SimulationRecord r;
  r.patient_id = std::move(h.patient_id);
  r.patient_file = std::move(h.patient_file);
  r.synthetic = h.synthetic;
  r.provenance = std::move(h.provenance);
  r.options = std::move(h.options);
  r.status = root.attr_string("status");
  r.reason = root.attr_string("reason");
  // Files written before the outcome was recorded have none.
  if (root.has_attr("outcome")) r.outcome = root.attr_string("outcome");
  r.parameters.for_each([&](const std::string& n, double& v, const char*) {
    v = root.open_group("parameters").read_scalar(n);
  });
  {
    const h5::Location sum = root.open_group("summary");
    for (const std::string& k : sum.member_names()) r.summary.emplace_back(k, sum.read_scalar(k));
  }
  if (root.exists("static_solve")) {
    const h5::Location st = root.open_group("static_solve");
    std::vector<hsize_t> d;
    r.static_residual_n = st.read_doubles("residual_n", &d, {-1}, "(iterations + 1)");
    r.static_failure = st.attr_string("failure");
  }
  const h5::Location ts = root.open_group("samples");
  std::vector<hsize_t> d;
  r.time_s = ts.read_doubles("time_s", &d, {-1}, "(S)");
  const long S = static_cast<long>(d[0]);
  r.observed_time_s = ts.read_doubles("observed_time_s", &d, {S}, "(S)");
  r.anterior_tip_mm = ts.read_doubles("anterior_tip_to_annulus_plane_mm", &d, {S}, "(S)");
  r.posterior_tip_mm = ts.read_doubles("posterior_tip_to_annulus_plane_mm", &d, {S}, "(S)");
  r.orifice_area_mm2 = ts.read_doubles("orifice_area_mm2", &d, {S}, "(S)");
  r.annulus_area_mm2 = ts.read_doubles("annulus_area_mm2", &d, {S}, "(S)");
  const std::vector<double> la = ts.read_doubles("la_surface", &d, {S, -1, -1, 3}, "(S, V, U, 3)");
  const int V = static_cast<int>(d[1]), U = static_cast<int>(d[2]);
  for (long s = 0; s < S; ++s) {
    LeafletGrid::Points P(U * V, 3);
    std::copy(la.begin() + s * U * V * 3, la.begin() + (s + 1) * U * V * 3, P.data());
    r.la_surface.emplace_back(U, V, std::move(P));
  }
  const h5::Location fin = root.open_group("final");
  const std::vector<double> X = fin.read_doubles("rest_positions", &d, {-1, 3}, "(N, 3)");
  const long N = static_cast<long>(d[0]);
  r.mesh.V =
      Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(X.data(), N, 3);
  const std::vector<double> Y = fin.read_doubles("final_positions", &d, {N, 3}, "(N, 3)");
  r.final_positions =
      Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(Y.data(), N, 3);
  const std::vector<int> T = fin.read_ints("tets", &d, {-1, 4}, "(E, 4)");
  const long E = static_cast<long>(d[0]);
  r.mesh.T =
      Eigen::Map<const Eigen::Matrix<int, Eigen::Dynamic, 4, Eigen::RowMajor>>(T.data(), E, 4);
  const std::vector<int> tag = fin.read_ints("tag", &d, {E}, "(E)");
  r.mesh.tag = Eigen::Map<const Eigen::VectorXi>(tag.data(), E);
  const std::vector<double> fib = fin.read_doubles("fibre", &d, {E, 3}, "(E, 3)");
  r.mesh.fibre =
      Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(fib.data(), E, 3);
  const std::vector<double> st = fin.read_doubles("strain_max_principal", &d, {E}, "(E)");
  r.element_strain = Eigen::Map<const Eigen::VectorXd>(st.data(), E);
  const std::vector<double> ss = fin.read_doubles("stress_von_mises", &d, {E}, "(E)");
  r.element_stress_mpa = Eigen::Map<const Eigen::VectorXd>(ss.data(), E);
  for (Eigen::Index e = 0; e < r.mesh.T.rows(); ++e) {
    for (int k = 0; k < 4; ++k) {
      if (r.mesh.T(e, k) < 0 || r.mesh.T(e, k) >= N)
        root.fail("final/tets", "node index out of range in element " + std::to_string(e));
    }
  }
  if (root.exists("orifice")) {
    std::optional<LeafletGrid> atrial, ventricular;
    r.orifice = h5::read_orifice(root.open_group("orifice"), &atrial, &ventricular);
    if (!atrial || !ventricular) root.fail("orifice", "needs la_surface and lv_surface");
    r.orifice_surface = std::move(*atrial);
    r.orifice_lv_surface = std::move(*ventricular);
  }
  return r;
}

std::string mvtwin_file_format(const std::filesystem::path& path) {
  const h5::Location root = h5::Location::open_file(path);
  return root.has_attr("format") ? root.attr_string("format") : std::string();
}

}  // namespace mvtwin
