#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <set>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

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

// Virtual patient 21 on a 12 x 6 model, optionally with a clip.
ClosureOptions small_export_options(bool clip = false) {
  ClosureOptions o;
  o.model.ures = 12;
  o.model.vres = 6;
  if (clip) o.clips.push_back({});
  return o;
}
ClosureScene small_scene(bool clip = false) {
  const Patient p = make_virtual_patient(21);
  return make_closure_scene(p.sequence, p.truth->parameters, small_export_options(clip));
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

// FEBio's "neo-Hookean transiso" (FEBioMech/FENeoHookeanTransIso.cpp, transcribed here): the
// Cauchy stress for deformation gradient F, fibre (symmetry axis) a0 = e1.
Eigen::Matrix3d nhti_stress(const Eigen::Matrix3d& F, double ep, double ez, double vz, double vp,
                            double gz) {
  const double J = F.determinant();
  Eigen::Vector3d a = F.col(0);
  const double lam = a.norm();
  a /= lam;
  const Eigen::Matrix3d B = F * F.transpose();
  const double I1 = B.trace(), I3 = J * J, I4 = lam * lam;
  const double gp = ep / (2 * (1 + vp));
  const double den = (1 + vp) * (ez * (-1 + vp) + 2 * ep * vz * vz);
  const double lamp = -(ep * (ez * vp + ep * vz * vz)) / den;
  const double lamz = (ez * ez * (-1 + vp * vp) - ep * (ep + 4 * (gp + gz) * (1 + vp)) * vz * vz +
                       ez * (2 * gz - ep * vp - 2 * gz * vp * vp - 2 * gp * (-1 + vp * vp) +
                             2 * ep * vz + 2 * ep * vp * vz)) /
                      den;
  const double alpha = (ep * (ep * vz * vz - ez * (vp * (-1 + vz) + vz))) / den;
  const Eigen::Vector3d Ba = B * a;
  Eigen::Matrix3d s;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      s(i, j) = 2 *
                (B(i, j) * (gp / 2 + alpha * (I4 - 1) / 4) +
                 (a(j) * Ba(i) + a(i) * Ba(j)) * (gz - gp) * I4 / 2 +
                 (i == j ? I3 * (-gp / (2 * I3) + (J - 1) * lamp / (2 * J)) : 0.0) +
                 a(i) * a(j) * I4 *
                     (gz / 2 + alpha * (I1 - 3) / 4 - gz / (2 * I4) - (gz - gp) * I4 +
                      (lam - 1) * lamz / (2 * lam))) /
                J;
  return s;
}

// The leaflets' FEBio law, with the constants valve.feb gives it, linearizes to mvtwin's
// transversely isotropic stiffness (finite differences of FEBio's stress at the reference), and
// unlike St Venant-Kirchhoff (FEBio's "orthotropic elastic", written before) it does not soften
// in compression: the first Piola stress of confined compression across the fibre grows
// monotonically to stretch 0.1, where St Venant-Kirchhoff's falls back towards zero below a
// stretch of 1/sqrt(3).
TEST(FebioExport, LeafletLawLinearizesToMvtwinsAndStiffensInCompression) {
  const ClosureOptions o = small_export_options();
  const ClosureScene scene = small_scene();
  const fs::path dir = fs::temp_directory_path() / ("mvtwin_law_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  export_scene(scene, o, dir, "law test", {});
  const std::string feb = slurp(dir / "valve.feb");
  fs::remove_all(dir);
  for (int k = 0; k < 2; ++k) {
    const size_t at = feb.find("<material id=\"" + std::to_string(k + 1) + "\"");
    ASSERT_NE(at, std::string::npos);
    const std::string m = feb.substr(at, feb.find("</material>", at) - at);
    ASSERT_NE(m.find("type=\"neo-Hookean transiso\""), std::string::npos) << m;
    const auto v = [&m](const std::string& tag) {
      const size_t p = m.find("<" + tag + ">");
      EXPECT_NE(p, std::string::npos) << tag;
      return std::stod(m.substr(p + tag.size() + 2, 24));
    };
    const double ep = v("Ep"), ez = v("Ez"), vz = v("vz"), vp = v("vp"), gz = v("gz");
    const auto sigma = [&](const Eigen::Matrix3d& F) { return nhti_stress(F, ep, ez, vz, vp, gz); };
    // Voigt (11, 22, 33, 23, 13, 12), engineering shear strains, as stiffness_local().
    const int vi[6][2] = {{0, 0}, {1, 1}, {2, 2}, {1, 2}, {0, 2}, {0, 1}};
    Eigen::Matrix<double, 6, 6> C;
    const double h = 1e-6;
    for (int c = 0; c < 6; ++c) {
      Eigen::Matrix3d Fp = Eigen::Matrix3d::Identity(), Fm = Eigen::Matrix3d::Identity();
      const int i = vi[c][0], j = vi[c][1];
      const double d = i == j ? h : h / 2;
      Fp(i, j) += d;
      Fm(i, j) -= d;
      if (i != j) {
        Fp(j, i) += d;
        Fm(j, i) -= d;
      }
      const Eigen::Matrix3d ds = (sigma(Fp) - sigma(Fm)) / (2 * h);
      for (int r = 0; r < 6; ++r) C(r, c) = ds(vi[r][0], vi[r][1]);
    }
    const Eigen::Matrix<double, 6, 6> ref = scene.leaflet_material[k].stiffness_local();
    EXPECT_LT((C - ref).cwiseAbs().maxCoeff(), 1e-6 * ref.cwiseAbs().maxCoeff())
        << "leaflet " << k << "\nFEBio:\n"
        << C << "\nmvtwin:\n"
        << ref;
    // Confined compression across the fibre: F = diag(1, l, 1).
    double previous = 0.0;
    for (double l = 0.95; l > 0.09; l -= 0.05) {
      const Eigen::Matrix3d F = Eigen::Vector3d(1.0, l, 1.0).asDiagonal();
      const double p22 = (F.determinant() * sigma(F) * F.inverse().transpose())(1, 1);
      EXPECT_LT(p22, previous) << "softens at stretch " << l;
      previous = p22;
    }
    // Stiffer than the co-rotational law, whose stress here is C22 (l - 1) = -0.9 C22 at 0.1.
    EXPECT_LT(previous, -ref(1, 1));
  }
}

// export_scene writes every file; valve.feb holds the whole scene (elements, nodes with the
// papillary tips, one boundary condition per prescribed node and axis, one spring per chorda
// end node and clip, load curves numbered 1..n and all referenced ones defined); the pressure
// profile and tips in boundary.csv are the scene's.
TEST(FebioExport, SceneFilesAreCompleteAndConsistent) {
  const ClosureOptions o = small_export_options(true);
  const ClosureScene scene = small_scene(true);
  const fs::path dir = fs::temp_directory_path() / ("mvtwin_scene_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  // Two elements as if the inversion guard had held them: neo-Hookean, in their own domains.
  const int last_element = scene.model.mesh.num_elements() - 1;
  const auto files =
      export_scene(scene, o, dir, "test\nsecond line -- with dashes", {0, last_element});
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
  // One spring per node of each chorda's cross-section, one per clip.
  size_t chorda_springs = 0;
  for (const SceneChorda& c : scene.chordae) chorda_springs += c.nodes.size();
  EXPECT_EQ(count(feb, "type=\"nonlinear spring\""),
            static_cast<int>(chorda_springs + scene.springs.size()));
  // The automatic time stepper, FEBio's own bandwidth optimization, and the contact potential
  // with the parameters derived from mvtwin's penalty. Two analysis steps (the closure, then the
  // load held while the damping's Maxwell branch relaxes), each with its stepper and solver.
  EXPECT_EQ(count(feb, "<time_stepper type=\"default\">"), 1);
  EXPECT_EQ(count(feb, "<time_stepper>"), 1);
  EXPECT_EQ(count(feb, "<max_retries>10</max_retries>"), 2);  // 10 halvings: dt / 1024
  // Failed steps are retried at half the step: FEBio uses the cutback only with aggressiveness
  // 1 (with 0 it shortens a retried step by dt / 26 each time).
  EXPECT_EQ(count(feb, "<aggressiveness>1</aggressiveness>"), 2);
  EXPECT_EQ(count(feb, "<cutback>0.5</cutback>"), 2);
  EXPECT_EQ(count(feb, "type=\"neo-Hookean transiso\""), 2);
  EXPECT_EQ(count(feb, "orthotropic elastic"), 0);
  EXPECT_EQ(count(feb, "<optimize_bw>1</optimize_bw>"), 2);
  // The node positions logged as text in mvtwin's order.
  EXPECT_EQ(count(feb,
                  "<node_data data=\"x;y;z\" delim=\" \" node_set=\"mvtwin_order\" "
                  "file=\"febio_nodes.txt\"/>"),
            1);
  EXPECT_EQ(count(feb, "type=\"contact potential\""), 1);
  const FebioContactPotential cp = febio_contact_potential(
      o.contact, o.contact.stiffness_per_area(scene.peak_pressure_mpa), scene.peak_pressure_mpa);
  const auto value_of = [&feb](const std::string& tag) {
    const size_t at = feb.find("<" + tag + ">");
    return at == std::string::npos ? -1.0 : std::stod(feb.substr(at + tag.size() + 2, 24));
  };
  EXPECT_NEAR(value_of("kc"), cp.kc, 1e-9 * cp.kc);
  EXPECT_EQ(value_of("R_in"), kFebioContactRangeFactor * o.contact.contact_mm);
  EXPECT_EQ(value_of("R_out"), kFebioContactRangeFactor * o.contact.alarm_mm);
  EXPECT_EQ(value_of("R0_min"), o.contact.exclusion_mm * o.contact.exclusion_mm);
  EXPECT_EQ(count(feb, "sliding-elastic"), 0);
  EXPECT_EQ(count(feb, "<ElementData type=\"mat_axis\""), 2);
  EXPECT_EQ(count(feb, "type=\"neo-Hookean\""), 2);  // one material per leaflet
  // mvtwin's stiffness-proportional damping as a Maxwell branch of all four materials, and the
  // load held for ten of its relaxation times after the closure.
  ASSERT_GT(o.rayleigh_stiffness, 0.0);
  EXPECT_EQ(count(feb, "type=\"viscoelastic\""), 4);
  EXPECT_EQ(count(feb, "<g1>1</g1>"), 4);
  EXPECT_EQ(value_of("t1"), o.rayleigh_stiffness);
  EXPECT_EQ(value_of("time_steps"), std::ceil(scene.duration() / o.dt - 1e-9));
  EXPECT_EQ(count(feb, "<step name=\"relax\">"), 1);
  {
    const size_t relax = feb.find("<step name=\"relax\">");
    ASSERT_NE(relax, std::string::npos);
    const std::string tail = feb.substr(relax, feb.find("</step>", relax) - relax);
    EXPECT_NE(tail.find("<time_steps>" + std::to_string(kFebioRelaxSteps) + "</time_steps>"),
              std::string::npos);
    const size_t at = tail.find("<step_size>");
    ASSERT_NE(at, std::string::npos);
    EXPECT_NEAR(std::stod(tail.substr(at + 11, 24)) * kFebioRelaxSteps,
                kFebioRelaxTimes * o.rayleigh_stiffness, 1e-12);
    // FEBio 4 refuses a type attribute on a step's time stepper and solver.
    EXPECT_EQ(tail.find("type="), std::string::npos);
  }
  {
    ClosureOptions undamped = o;
    undamped.rayleigh_stiffness = 0.0;
    const fs::path file = dir / "undamped.feb";
    write_febio(file, scene, undamped, "undamped", {});
    const std::string plain = slurp(file);
    EXPECT_EQ(count(plain, "type=\"viscoelastic\""), 0);
    EXPECT_EQ(count(plain, "<Step>"), 0);
    EXPECT_EQ(count(plain, "type=\"neo-Hookean transiso\""), 2);
    const size_t at = plain.find("<time_steps>");
    ASSERT_NE(at, std::string::npos);
    EXPECT_EQ(std::stod(plain.substr(at + 12, 24)), std::ceil(scene.duration() / o.dt - 1e-9));
  }
  const auto elements_in = [&feb](const std::string& domain) {
    const size_t at = feb.find("<Elements type=\"tet10\" name=\"" + domain + "\">");
    if (at == std::string::npos) return 0;
    return count(feb.substr(at, feb.find("</Elements>", at) - at), "<elem id=");
  };
  const bool first_anterior = scene.model.mesh.tag[0] == static_cast<int>(LeafletTag::kAnterior);
  const bool last_anterior =
      scene.model.mesh.tag[last_element] == static_cast<int>(LeafletTag::kAnterior);
  EXPECT_EQ(elements_in("anterior_guarded"), int(first_anterior) + int(last_anterior));
  EXPECT_EQ(elements_in("posterior_guarded"), int(!first_anterior) + int(!last_anterior));
  EXPECT_EQ(elements_in("anterior") + elements_in("posterior") + elements_in("anterior_guarded") +
                elements_in("posterior_guarded"),
            mesh.num_elements());
  // Two comments (the header, the contact's gap): XML comments must not contain -- inside.
  EXPECT_EQ(count(feb, "--"), 4) << "XML comments must not contain -- (only <!-- and -->)";
  EXPECT_EQ(count(feb, "<!--"), 2);
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

// FEBio's contact potential, integrated between two parallel surfaces, is mvtwin's penalty
// with the distances doubled: zero from R_out = 2 x the alarm distance, k (R_out - R_in) at R_in
// = 2 x the contact distance, growing monotonically as the gap closes (through FEBio's wall
// below R_in), and pressing with the peak pressure at gap_at_peak, for a low and a high peak.
TEST(FebioExport, ContactPotentialIsMvtwinsPenaltyAtTwiceTheDistances) {
  SelfContactOptions c;
  for (const double peak : {0.0107, 0.016, 0.025}) {
    const double k = c.stiffness_per_area(peak);
    const FebioContactPotential cp = febio_contact_potential(c, k, peak);
    EXPECT_DOUBLE_EQ(cp.r_in, 2.0 * c.contact_mm);
    EXPECT_DOUBLE_EQ(cp.r_out, 2.0 * c.alarm_mm);
    const double w = cp.r_out - cp.r_in;
    const double c1 = 0.5 * cp.p * cp.kc / (w * std::pow(cp.r_in, cp.p + 1.0));
    const double c2 = cp.kc / std::pow(cp.r_in, cp.p) - c1 * w * w;
    auto f = [&](double r) {
      if (r < cp.r_in) return cp.kc / std::pow(r, cp.p) - c2;
      if (r < cp.r_out) return c1 * (r - cp.r_out) * (r - cp.r_out);
      return 0.0;
    };
    auto pressure = [&](double g) {
      const int steps = 20000;
      double sum = 0.0;
      const double h = (cp.r_out - g) / steps;
      for (int i = 0; i < steps; ++i) sum += f(g + (i + 0.5) * h) * h;  // midpoint rule
      return 2.0 * M_PI * g * sum;
    };
    EXPECT_NEAR(pressure(cp.r_in), k * w, 1e-6 * k * w) << "peak " << peak;
    EXPECT_NEAR(pressure(cp.gap_at_peak), peak, 1e-6 * peak) << "peak " << peak;
    EXPECT_NEAR(k * (c.alarm_mm - cp.mvtwin_gap_at_peak), peak, 1e-12 * peak);
    EXPECT_GT(cp.gap_at_peak, cp.mvtwin_gap_at_peak);  // the cost of the doubled range
    EXPECT_GT(cp.gap_at_peak, cp.r_in);
    EXPECT_LT(cp.gap_at_peak, cp.r_out);
    EXPECT_EQ(pressure(cp.r_out), 0.0);
    double last = 0.0;
    for (double g = cp.r_out - 0.01; g > 0.05; g -= 0.01) {
      const double pg = pressure(g);
      EXPECT_GT(pg, last) << "gap " << g;
      last = pg;
    }
    EXPECT_DOUBLE_EQ(cp.r0_min, c.exclusion_mm * c.exclusion_mm);
  }
}

// Each chorda's springs: one per cross-section node with equal shares, rest lengths shifted so
// that the springs together pull with the force of mvtwin's chorda at its mean point, up to the
// law's slope times how far one spring's elongation strays from the mean point's (second order:
// the tip moved along the chorda; checked to be a small part of the force), and never one
// surface node alone.
TEST(FebioExport, ChordaSpringsPullLikeTheMeanPoint) {
  const ClosureScene scene = small_scene();
  const SolidMesh& mesh = scene.model.mesh;
  for (int c = 0; c < static_cast<int>(scene.chordae.size()); ++c) {
    const SceneChorda& ch = scene.chordae[c];
    const auto parts = febio_chorda_springs(scene, c);
    ASSERT_EQ(parts.size(), ch.nodes.size());
    ASSERT_GT(parts.size(), 1u);
    double shares = 0.0;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (int i : ch.nodes) mean += mesh.V.row(i).transpose();
    mean /= static_cast<double>(ch.nodes.size());
    const Eigen::Vector3d tip = scene.papillary_tip(ch.tip, 0.0);
    const Eigen::Vector3d dir = (tip - mean).normalized();
    for (const FebioChordaSpring& sp : parts) shares += sp.scale;
    EXPECT_NEAR(shares, 1.0, 1e-12);
    for (double pull : {0.0, 0.5, 1.0, 2.0}) {  // the tip moved away along the chorda, mm
      const Eigen::Vector3d t = tip + pull * dir;
      const double l_mean = (t - mean).norm();
      const double expected = ch.law.area * ch.law.stress(l_mean / ch.rest_length - 1.0);
      double force = 0.0, mismatch = 0.0;
      for (const FebioChordaSpring& sp : parts) {
        const double l = (t - mesh.V.row(sp.node).transpose()).norm();
        EXPECT_NEAR(sp.initial, (tip - mesh.V.row(sp.node).transpose()).norm(), 1e-12);
        const auto curve = febio_spring_curve(sp.mean_length, sp.rest, &ch.law, 0.0);
        force += sp.scale * evaluate(curve, l - sp.initial);
        // How far this spring's elongation strays from the mean point's (second order in the
        // cross-section's size over the chorda's length).
        mismatch = std::max(mismatch, std::abs((l - sp.initial) - (l_mean - sp.mean_length)));
      }
      // Exact up to the law's stiffest slope times that mismatch.
      const double slope = ch.law.area * std::max(ch.law.e_low, ch.law.e_high) / ch.rest_length;
      EXPECT_NEAR(force, expected, 1e-9 + slope * mismatch) << "chorda " << c << " pull " << pull;
      if (expected > 0.01) {
        EXPECT_LT(slope * mismatch, 0.2 * expected) << "chorda " << c;
      }
    }
  }
}

// The node numbering is a permutation and shrinks the skyline profile (sum over rows of the
// distance to the row's first nonzero in the node graph) well below mvtwin's own numbering
// (corner nodes, then mid-edge nodes).
TEST(FebioExport, NodeOrderShrinksTheProfile) {
  const Patient p = make_virtual_patient(1);
  ClosureOptions o;
  o.model.ures = 30;
  o.model.vres = 30;
  const ClosureScene scene = make_closure_scene(p.sequence, p.truth->parameters, o);
  const SolidMesh& mesh = scene.model.mesh;
  const std::vector<int> order = febio_node_order(mesh);
  ASSERT_EQ(static_cast<int>(order.size()), mesh.num_nodes());
  std::vector<int> rank(order.size(), -1);
  for (size_t k = 0; k < order.size(); ++k) {
    ASSERT_EQ(rank[order[k]], -1) << "node " << order[k] << " numbered twice";
    rank[order[k]] = static_cast<int>(k);
  }
  auto profile = [&](auto&& number) {
    std::vector<long> first(order.size());
    for (size_t i = 0; i < first.size(); ++i) first[i] = number(static_cast<int>(i));
    for (int e = 0; e < mesh.num_elements(); ++e)
      for (int a = 0; a < mesh.nodes_per_element(); ++a)
        for (int b = 0; b < mesh.nodes_per_element(); ++b) {
          const int i = mesh.T(e, a), j = mesh.T(e, b);
          first[i] = std::min<long>(first[i], number(j));
        }
    long sum = 0;
    for (size_t i = 0; i < first.size(); ++i) sum += number(static_cast<int>(i)) - first[i];
    return sum;
  };
  const long natural = profile([](int i) { return i; });
  const long reordered = profile([&](int i) { return rank[i]; });
  std::cout << "profile (nodes): mvtwin order " << natural << ", FEBio order " << reordered << "\n";
  EXPECT_LT(reordered, natural / 4);
}

// Rim faces: boundary faces of the elements, none on the atrial or ventricular surface or
// wholly held; they include every free-edge corner node of both leaflets, and each faces away
// from its element.
TEST(FebioExport, RimFacesCoverTheFreeEdge) {
  const ClosureScene scene = small_scene();
  const ValveModel& m = scene.model;
  const std::vector<RimFace> rims = rim_faces(scene);
  ASSERT_FALSE(rims.empty());
  std::set<int> on_rim;
  for (const RimFace& r : rims) {
    on_rim.insert({r.a, r.b, r.c});
    const int la = r.a / m.surface_nodes;
    EXPECT_FALSE(la == r.b / m.surface_nodes && la == r.c / m.surface_nodes)
        << "a rim face on one surface";
  }
  int free_edge = 0;
  for (int i = 0; i < m.surface_nodes; ++i) {
    if (m.surface_st(i, 1) < 1.0 - 1e-9) continue;  // t = 1: the free edge
    ++free_edge;
    EXPECT_TRUE(on_rim.count(m.node(i, 0)) && on_rim.count(m.node(i, m.options.layers)))
        << "free-edge node " << i << " not on a rim face";
  }
  EXPECT_GT(free_edge, 0);
  // Outward: the element's remaining corner lies behind each rim face.
  const SolidMesh& mesh = m.mesh;
  for (const RimFace& r : rims) {
    const Eigen::Vector3d a = mesh.V.row(r.a), b = mesh.V.row(r.b), c = mesh.V.row(r.c);
    const Eigen::Vector3d nrm = (b - a).cross(c - a);
    bool found = false;
    for (int e = 0; e < mesh.num_elements() && !found; ++e) {
      std::set<int> corners;
      for (int k = 0; k < 4; ++k) corners.insert(mesh.T(e, k));
      if (!corners.count(r.a) || !corners.count(r.b) || !corners.count(r.c)) continue;
      for (int k = 0; k < 4; ++k) {
        const int d = mesh.T(e, k);
        if (d == r.a || d == r.b || d == r.c) continue;
        EXPECT_LT(nrm.dot(Eigen::Vector3d(mesh.V.row(d)) - a), 0.0) << "rim face facing in";
        found = true;
      }
    }
    EXPECT_TRUE(found);
  }
}

}  // namespace
}  // namespace mvtwin::forward
