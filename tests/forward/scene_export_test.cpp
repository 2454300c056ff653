#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "mvtwin/core/virtual_patient.h"
#include "mvtwin/forward/closure_scene.h"
#include "mvtwin/forward/closure_simulation.h"
#include "mvtwin/forward/febio_export.h"
#include "mvtwin/forward/model_vtk.h"

namespace mvtwin::forward {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

int count(const std::string& text, const std::string& what) {
  int n = 0;
  for (size_t i = text.find(what); i != std::string::npos; i = text.find(what, i + 1)) ++n;
  return n;
}

// Linear interpolation of a curve, extrapolated linearly at both ends (FEBio "extrapolate").
double evaluate(const std::vector<std::pair<double, double>>& c, double x) {
  size_t k = 1;
  while (k + 1 < c.size() && x > c[k].first) ++k;
  const auto& [x0, y0] = c[k - 1];
  const auto& [x1, y1] = c[k];
  return y0 + (y1 - y0) * (x - x0) / (x1 - x0);
}

// The exported spring curve reproduces the chorda law: at any elongation the force is A0 sigma
// of the strain relative to the rest length (not the reference length), zero when slack.
TEST(FebioExport, SpringCurveFollowsTheChordaLaw) {
  for (const ChordaLaw& law : {ChordaLaw::marginal(), ChordaLaw::basal()}) {
    for (double initial : {12.0, 15.0}) {
      const double rest = 14.0;  // slack at rest (12) or taut (15)
      const auto curve = febio_spring_curve(initial, rest, &law, 0.0);
      for (double strain : {-0.3, -0.01, 0.0, 0.01, 0.025, 0.04, 0.05, 0.2, 1.5}) {
        const double length = rest * (1.0 + strain);
        const double expected = law.area * law.stress(strain);
        EXPECT_NEAR(evaluate(curve, length - initial), expected, 1e-9 * std::max(1.0, expected))
            << "strain " << strain << " initial " << initial;
      }
    }
  }
  const auto clip = febio_spring_curve(10.0, 1.6, nullptr, 9.8);
  EXPECT_NEAR(evaluate(clip, 2.6 - 10.0), 9.8, 1e-9);
  EXPECT_NEAR(evaluate(clip, 1.0 - 10.0), 0.0, 1e-12);
}

// export_scene writes every file; valve.feb holds the whole scene (elements, nodes with the
// papillary tips, one boundary condition per prescribed node and axis, one spring per chorda
// end node and clip, load curves numbered 1..n and all referenced ones defined); the pressure
// profile and tips in boundary.csv are the scene's.
TEST(FebioExport, SceneFilesAreCompleteAndConsistent) {
  const Patient p = make_virtual_patient(21);
  ClosureOptions o;
  o.model.ures = 12;
  o.model.vres = 6;
  o.clips.push_back({});
  const ClosureScene scene = make_closure_scene(p.sequence, p.truth->parameters, o);
  const fs::path dir = fs::temp_directory_path() / ("mvtwin_scene_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const auto files = export_scene(scene, o, dir, "test\nsecond line -- with dashes");
  for (const char* f :
       {"leaflets.vtu", "leaflets_quadratic.vtu", "chordae.vtp", "pressure_surface.vtp",
        "boundary.csv", "annulus_motion.csv", "boundary.pvd", "valve.feb"}) {
    EXPECT_TRUE(fs::exists(dir / f)) << f;
  }
  const std::string feb = slurp(dir / "valve.feb");
  const SolidMesh& mesh = scene.model.mesh;
  EXPECT_EQ(count(feb, "<elem id="), mesh.num_elements());
  EXPECT_EQ(count(feb, "<node id="), mesh.num_nodes() + 2);
  EXPECT_EQ(count(feb, "type=\"prescribed displacement\""),
            3 * (static_cast<int>(scene.prescribed.size()) + 2));
  // One spring per chorda (cross-sections of 3 nodes: the middle one) and per clip.
  EXPECT_EQ(count(feb, "type=\"nonlinear spring\""),
            static_cast<int>(scene.chordae.size() + scene.springs.size()));
  EXPECT_EQ(count(feb, "<ElementData type=\"mat_axis\""), 2);
  EXPECT_EQ(count(feb, "--"), 2) << "XML comments must not contain -- (only <!-- and -->)";
  const int curves = count(feb, "<load_controller id=");
  // The integers following each occurrence of `key` (for example `lc="` -> 3).
  const auto numbers_after = [&feb](const std::string& key) {
    std::set<int> out;
    for (std::size_t at = feb.find(key); at != std::string::npos; at = feb.find(key, at + 1))
      out.insert(std::stoi(feb.substr(at + key.size(), 12)));
    return out;
  };
  const std::set<int> defined = numbers_after("<load_controller id=\""),
                      used = numbers_after(" lc=\"");
  EXPECT_EQ(static_cast<int>(defined.size()), curves);
  EXPECT_EQ(*defined.begin(), 1);
  EXPECT_EQ(*defined.rbegin(), curves);
  for (int u : used) EXPECT_TRUE(defined.count(u)) << "load curve " << u;
  // Well-formed XML, when Debian's python3 is there to check it.
  if (fs::exists("/usr/bin/python3")) {
    const std::string cmd =
        "/usr/bin/python3 -c \"import sys, xml.etree.ElementTree as E; "
        "E.parse(sys.argv[1])\" " +
        (dir / "valve.feb").string();
    EXPECT_EQ(std::system(cmd.c_str()), 0) << "valve.feb is not well-formed XML";
  }
  // boundary.csv: pressure from 0 to the peak, tips at end-diastole first.
  std::ifstream csv(dir / "boundary.csv");
  std::string line, first, last;
  while (std::getline(csv, line)) {
    if (line.empty() || line[0] == '#' || line[0] == 't') continue;
    if (first.empty()) first = line;
    last = line;
  }
  auto field = [](const std::string& row, int k) {
    std::stringstream s(row);
    std::string item;
    for (int i = 0; i <= k; ++i) std::getline(s, item, ',');
    return std::stod(item);
  };
  EXPECT_EQ(field(first, 1), 0.0);
  EXPECT_NEAR(field(last, 1), scene.peak_pressure_mpa, 1e-9 * scene.peak_pressure_mpa);
  EXPECT_NEAR(field(last, 0), scene.duration(), 1e-9);
  EXPECT_NEAR(field(first, 2), scene.papillary_tip(0, 0.0).x(), 1e-6);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mvtwin::forward
