#include "orifice_io.h"

#include <algorithm>

namespace mvtwin::h5 {
namespace {

std::vector<double> flat(const LeafletGrid& g) {
  return std::vector<double>(g.points().data(), g.points().data() + g.points().size());
}

void write_grid(const Location& g, const std::string& name, const LeafletGrid& grid) {
  const auto f = flat(grid);
  g.write(name, f, {static_cast<hsize_t>(grid.vres()), static_cast<hsize_t>(grid.ures()), 3}, "mm");
}

}  // namespace

void write_orifice(const Location& parent, const RegurgitantOrifice& o,
                   const LeafletGrid* la_surface, const LeafletGrid* lv_surface) {
  const Location g = parent.create_group("orifice", true);
  g.attr("description",
         std::string("regurgitant orifice of the closed valve (core/regurgitant_orifice.h): "
                     "openings are [area mm^2, begin, end (0 anterolateral - 1 posteromedial "
                     "commissure), length mm, widest gap mm]; columns are the narrowest gap of "
                     "every leaflet column to the other leaflet (a on the column, b on the "
                     "other leaflet); la_surface and lv_surface are the fine end surfaces (atrial, "
                     "ventricular) "
                     "it was measured on"));
  g.write_scalar("aroa_mm2", o.aroa_mm2, "mm^2");
  g.write_scalar("eroa_mm2", o.eroa_mm2, "mm^2");
  g.attr("mr_grade", std::string(mr_grade_name(o.grade)));
  g.write_scalar("seal_mm", o.options.seal_mm, "mm");
  g.write_scalar("contraction_coefficient", o.options.contraction_coefficient, "1");
  g.write_scalar("central_fraction", o.options.central_fraction, "1");
  g.write_scalar("coaptation_length_mm", o.coaptation_length_mm, "mm");
  g.write_scalar("coaptation_depth_mm", o.coaptation_depth_mm, "mm");
  g.write_scalar("coapting_fraction", o.coapting_fraction, "1");
  std::vector<double> op;
  for (const Opening& x : o.openings)
    op.insert(op.end(), {x.area_mm2, x.begin, x.end, x.length_mm, x.max_gap_mm});
  g.write("openings", op, {o.openings.size(), 5});
  const hsize_t C = o.columns.size();
  std::vector<double> pos, gap, ab;
  std::vector<int> anterior;
  for (const ColumnGap& c : o.columns) {
    pos.push_back(c.position);
    gap.push_back(c.gap_mm);
    anterior.push_back(c.anterior ? 1 : 0);
    ab.insert(ab.end(), {c.a.x(), c.a.y(), c.a.z(), c.b.x(), c.b.y(), c.b.z()});
  }
  g.write("column_position", pos, {C});
  g.write("column_gap_mm", gap, {C}, "mm");
  g.write("column_anterior", anterior, {C});
  g.write("column_points", ab, {C, 2, 3}, "mm");
  if (la_surface) write_grid(g, "la_surface", *la_surface);
  if (lv_surface) write_grid(g, "lv_surface", *lv_surface);
}

std::optional<LeafletGrid> read_grid(const Location& g, const std::string& name) {
  if (!g.exists(name)) return std::nullopt;
  std::vector<hsize_t> d;
  const std::vector<double> p = g.read_doubles(name, &d, {-1, -1, 3}, "(V, U, 3)");
  const int V = static_cast<int>(d[0]), U = static_cast<int>(d[1]);
  if (U < 8 || U % 2 || V < 3) g.fail(name, "grid too small or ures odd");
  LeafletGrid::Points P(static_cast<Eigen::Index>(U) * V, 3);
  std::copy(p.begin(), p.end(), P.data());
  return LeafletGrid(U, V, std::move(P));
}

RegurgitantOrifice read_orifice(const Location& g, std::optional<LeafletGrid>* la,
                                std::optional<LeafletGrid>* lv) {
  RegurgitantOrifice o;
  o.aroa_mm2 = g.read_scalar("aroa_mm2");
  o.eroa_mm2 = g.read_scalar("eroa_mm2");
  o.grade = mr_grade_of(o.eroa_mm2);
  o.options.seal_mm = g.read_scalar("seal_mm");
  o.options.contraction_coefficient = g.read_scalar("contraction_coefficient");
  o.options.central_fraction = g.read_scalar("central_fraction");
  o.coaptation_length_mm = g.read_scalar("coaptation_length_mm");
  o.coaptation_depth_mm = g.read_scalar("coaptation_depth_mm");
  o.coapting_fraction = g.read_scalar("coapting_fraction");
  std::vector<hsize_t> d;
  const std::vector<double> op = g.read_doubles("openings", &d, {-1, 5}, "(n, 5)");
  for (size_t i = 0; i < d[0]; ++i)
    o.openings.push_back({op[5 * i], op[5 * i + 1], op[5 * i + 2], op[5 * i + 3], op[5 * i + 4]});
  const std::vector<double> pos = g.read_doubles("column_position", &d, {-1}, "(C)");
  const long C = static_cast<long>(d[0]);
  const std::vector<double> gap = g.read_doubles("column_gap_mm", &d, {C}, "(C)");
  const std::vector<int> ant = g.read_ints("column_anterior", &d, {C}, "(C)");
  const std::vector<double> ab = g.read_doubles("column_points", &d, {C, 2, 3}, "(C, 2, 3)");
  for (long i = 0; i < C; ++i) {
    ColumnGap c;
    c.position = pos[i];
    c.gap_mm = gap[i];
    c.anterior = ant[i] != 0;
    c.a = Eigen::Vector3d(ab[6 * i], ab[6 * i + 1], ab[6 * i + 2]);
    c.b = Eigen::Vector3d(ab[6 * i + 3], ab[6 * i + 4], ab[6 * i + 5]);
    o.columns.push_back(c);
  }
  *la = read_grid(g, "la_surface");
  *lv = read_grid(g, "lv_surface");
  if (*la && *lv && ((*la)->ures() != (*lv)->ures() || (*la)->vres() != (*lv)->vres()))
    g.fail("lv_surface", "not on the grid of la_surface");
  return o;
}

}  // namespace mvtwin::h5
