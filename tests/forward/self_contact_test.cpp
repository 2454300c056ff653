#include "mvtwin/forward/self_contact.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "mvtwin/core/error.h"

namespace mvtwin::forward {
namespace {

// Two square plates of n x n vertices (spacing 1 mm) facing each other at distance gap; every
// vertex and triangle of one plate can touch the other, and the plane coordinates put the
// plates 100 mm apart so that neither is excluded.
struct Plates {
  SelfContact::Surface surface;
  Eigen::VectorXd x;
};

Plates make_plates(int n, double gap, double shift = 0.3) {
  Plates p;
  const int per = n * n;
  p.x.resize(3 * 2 * per);
  p.surface.plane.resize(2 * per, 2);
  for (int k = 0; k < 2; ++k) {
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        const int id = k * per + j * n + i;
        p.x.segment<3>(3 * id) = Eigen::Vector3d(i + k * shift, j + k * shift, k * gap);
        p.surface.plane.row(id) = Eigen::RowVector2d(i + 100.0 * k, j);
        p.surface.vertices.push_back(id);
        p.surface.vertex_plane.push_back(id);
        p.surface.vertex_area.push_back(1.0);
      }
    }
    for (int j = 0; j + 1 < n; ++j) {
      for (int i = 0; i + 1 < n; ++i) {
        const int a = k * per + j * n + i, b = a + 1, c = a + n + 1, d = a + n;
        p.surface.triangles.push_back({a, b, c});
        p.surface.triangles.push_back({a, c, d});
        p.surface.triangle_plane.push_back({a, b, c});
        p.surface.triangle_plane.push_back({a, c, d});
        // Normals +z: out of the lower plate (towards the upper), into the upper one.
        p.surface.triangle_outward.push_back(k == 0 ? 1 : -1);
        p.surface.triangle_outward.push_back(k == 0 ? 1 : -1);
      }
    }
  }
  return p;
}

// Penalty stiffness per unit area (N/mm^3) and deepest pairing of the tests' contact.
constexpr double kStiffness = 0.05, kMaxDepth = 0.6;

SelfContactOptions options() {
  SelfContactOptions o;
  o.friction = 0.0;
  o.wall_factor = 0.0;  // the plain penalty unless a test asks for the wall
  return o;
}

TEST(SelfContact, PlatesWithinAlarmArePushedApart) {
  Plates p = make_plates(5, 0.4);
  SelfContact c(p.surface, options(), kStiffness, kMaxDepth);
  const int found = c.detect(p.x);
  // Every vertex of each plate above/below the other plate's interior is in contact.
  EXPECT_GE(found, 2 * 9);
  Eigen::VectorXd f = Eigen::VectorXd::Zero(p.x.size()), v = f;
  std::vector<Eigen::Triplet<double>> trip;
  const double energy = c.add(v, &f, &trip, 1.0, 1.0);
  EXPECT_GT(energy, 0.0);
  // Net force zero (action = reaction); the lower plate is pushed down, the upper one up.
  double lower = 0.0, upper = 0.0;
  for (int i = 0; i < 25; ++i) lower += f[3 * i + 2];
  for (int i = 25; i < 50; ++i) upper += f[3 * i + 2];
  EXPECT_LT(lower, 0.0);
  EXPECT_GT(upper, 0.0);
  EXPECT_NEAR(lower + upper, 0.0, 1e-12);
  EXPECT_NEAR(f.norm() > 0 ? (f.segment(0, 75).sum() + f.segment(75, 75).sum()) : 0.0, 0.0, 1e-9);
}

TEST(SelfContact, ForceIsMinusEnergyGradient) {
  Plates p = make_plates(4, 0.35);
  SelfContact c(p.surface, options(), kStiffness, kMaxDepth);
  ASSERT_GT(c.detect(p.x), 0);
  Eigen::VectorXd f = Eigen::VectorXd::Zero(p.x.size()), v = f;
  std::vector<Eigen::Triplet<double>> trip;
  c.add(v, &f, &trip, 1.0, 1.0);
  // Central differences of the energy with the pairs re-detected at each perturbed state.
  const double h = 1e-6;
  double worst = 0.0;
  for (int d = 0; d < p.x.size(); ++d) {
    Eigen::VectorXd xp = p.x, xm = p.x;
    xp[d] += h;
    xm[d] -= h;
    Eigen::VectorXd g = Eigen::VectorXd::Zero(p.x.size());
    std::vector<Eigen::Triplet<double>> t2;
    SelfContact cp(p.surface, options(), kStiffness, kMaxDepth),
        cm(p.surface, options(), kStiffness, kMaxDepth);
    cp.detect(xp);
    cm.detect(xm);
    const double ep = cp.add(v, &g, &t2, 1, 1), em = cm.add(v, &g, &t2, 1, 1);
    worst = std::max(worst, std::abs(-(ep - em) / (2 * h) - f[d]));
  }
  EXPECT_LT(worst, 1e-6 * std::max(1.0, f.lpNorm<Eigen::Infinity>()));
}

TEST(SelfContact, FarPlatesSkipTheSearchUntilTheyApproach) {
  Plates p = make_plates(5, 6.0);
  SelfContact c(p.surface, options(), kStiffness, kMaxDepth);
  EXPECT_EQ(c.detect(p.x), 0);
  EXPECT_EQ(c.searches(), 1);
  // Small motion: nothing can have come within reach, the search is skipped.
  Eigen::VectorXd x = p.x;
  for (int i = 25; i < 50; ++i) x[3 * i + 2] -= 0.5;
  EXPECT_EQ(c.detect(x), 0);
  EXPECT_EQ(c.reused(), 1);
  // The upper plate comes down to 0.4 mm: searched again and found.
  for (int i = 25; i < 50; ++i) x[3 * i + 2] = 0.4;
  EXPECT_GT(c.detect(x), 0);
  EXPECT_EQ(c.searches(), 2);
}

TEST(SelfContact, NeighboursInThePlaneAreExcluded) {
  Plates p = make_plates(5, 0.4);
  // Put the plates side by side in the plane: all within the exclusion distance.
  for (int id = 25; id < 50; ++id) p.surface.plane(id, 0) -= 100.0;
  SelfContact c(p.surface, options(), kStiffness, kMaxDepth);
  EXPECT_EQ(c.detect(p.x), 0);
}

// The upper plate's vertices, free, pressed down with a force per area p onto the fixed lower
// plate and integrated by implicit Euler with the contact stiffness: each comes to rest at the
// distance where the penalties balance the load, d = alarm - p / (2 stiffness_per_area) (vertices
// of both plates push on the other's triangles), from either
// an approach slow enough not to tunnel (larger steps are the simulator's business: it halves
// steps that SelfContact::find_crossing catches).
TEST(SelfContact, PressedPlateRestsAtThePenaltyEquilibrium) {
  for (double dt : {1e-3}) {
    Plates p = make_plates(5, 1.5, 0.0);
    SelfContactOptions o = options();
    SelfContact c(p.surface, o, kStiffness, kMaxDepth);
    const double load = 0.01;  // N/mm^2 on 1 mm^2 per vertex
    const double mass = 1e-6, damping = 20.0;
    Eigen::VectorXd x = p.x, v = Eigen::VectorXd::Zero(x.size());
    for (int step = 0; step < 4000; ++step) {
      c.detect(x);
      Eigen::VectorXd f = Eigen::VectorXd::Zero(x.size());
      std::vector<Eigen::Triplet<double>> trip;
      c.add(v, &f, &trip, dt * dt, dt);
      Eigen::VectorXd diag = Eigen::VectorXd::Constant(x.size(), mass * (1 + damping * dt));
      for (const auto& t : trip) {
        if (t.row() == t.col()) diag[t.row()] += t.value();
      }
      for (int i = 25; i < 50; ++i) {
        for (int k = 0; k < 3; ++k) {
          const int d = 3 * i + k;
          const double fd = f[d] - (k == 2 ? load : 0.0) - damping * mass * v[d];
          v[d] += dt * fd / diag[d];  // one linearized implicit step (diagonal system)
        }
      }
      for (int i = 25; i < 50; ++i) x.segment<3>(3 * i) += dt * v.segment<3>(3 * i);
    }
    // Both plates' vertices push on the other's triangles: twice the stiffness of one pair.
    const double expected = o.alarm_mm - load / (2.0 * kStiffness);
    for (int i = 25; i < 50; ++i) {
      EXPECT_NEAR(x[3 * i + 2], expected, 0.05) << "dt " << dt << " vertex " << i;
    }
  }
}

// Continuous collision detection: a plate moved through the other in one step is caught
// (whether or not the Verlet list covers the step); a slow approach, a slide or a way back out
// is not.
TEST(SelfContact, CrossingInOneStepIsCaught) {
  Plates p = make_plates(4, 1.0);
  SelfContact c(p.surface, options(), kStiffness, kMaxDepth);
  c.detect(p.x);
  Eigen::VectorXd slow = p.x, slide = p.x, through = p.x, far_through = p.x;
  for (int i = 16; i < 32; ++i) {
    slow[3 * i + 2] -= 0.5;         // to 0.5 mm: approaching, not crossing
    slide[3 * i] += 0.4;            // sideways at 1 mm
    through[3 * i + 2] -= 1.5;      // to -0.5 mm: through the lower plate
    far_through[3 * i + 2] -= 9.0;  // far beyond: the candidate list does not cover it
  }
  EXPECT_EQ(c.find_crossing(p.x, slow), -1);
  EXPECT_EQ(c.find_crossing(p.x, slide), -1);
  const int v = c.find_crossing(p.x, through);
  EXPECT_GE(v, 0);
  EXPECT_GE(c.find_crossing(p.x, far_through), 0);
  // Moving back out (from the lower plate's inner side to its outer side) is not a crossing.
  EXPECT_EQ(c.find_crossing(through, p.x), -1);
  // Plates far apart moving together: no crossing.
  Plates far = make_plates(4, 8.0);
  SelfContact c2(far.surface, options(), kStiffness, kMaxDepth);
  c2.detect(far.x);
  Eigen::VectorXd moved = far.x;
  for (int i = 0; i < moved.size(); i += 3) moved[i] += 0.2;
  EXPECT_EQ(c2.find_crossing(far.x, moved), -1);
}

// With ccd_depth_mm a step may leave a vertex up to that deep inside the other plate (the law
// pushes it back out): what is crossed is the surface moved inwards by the depth, so a vertex
// resting on the surface and passing it by round-off is not refused, and a deeper one is, also
// from a start already inside. Both searches: the candidate list (plates 0.3 mm apart at the
// search) and the swept boxes (1 mm apart, the step moves farther than margin / 2).
TEST(SelfContact, CrossingsShallowerThanTheCcdDepthAreLeftToTheLaw) {
  for (double gap : {0.3, 1.0}) {
    Plates p = make_plates(4, gap);
    SelfContactOptions tolerant = options();
    tolerant.ccd_depth_mm = 0.1;
    SelfContact strict(p.surface, options(), kStiffness, kMaxDepth),
        c(p.surface, tolerant, kStiffness, kMaxDepth);
    strict.detect(p.x);
    c.detect(p.x);
    auto upper_at = [&](double z) {
      Eigen::VectorXd x = p.x;
      for (int i = 16; i < 32; ++i) x[3 * i + 2] = z;
      return x;
    };
    const Eigen::VectorXd above = upper_at(0.01), shallow = upper_at(-0.05), deep = upper_at(-0.2);
    EXPECT_GE(strict.find_crossing(above, shallow), 0) << "gap " << gap;
    EXPECT_EQ(c.find_crossing(above, shallow), -1) << "gap " << gap;
    EXPECT_GE(c.find_crossing(above, deep), 0) << "gap " << gap;
    EXPECT_GE(c.find_crossing(shallow, deep), 0) << "gap " << gap;
    EXPECT_EQ(strict.find_crossing(shallow, deep), -1) << "started inside: not a crossing";
    EXPECT_EQ(c.find_crossing(deep, shallow), -1) << "on the way back out";
    EXPECT_EQ(c.find_crossing(deep, above), -1) << "on the way back out";
  }
  // Never as deep as half the depth where the leaflet's other face answers: with a maximum
  // depth of 0.1 mm the 0.1 mm allowed becomes 0.05.
  {
    Plates p = make_plates(4, 1.0);
    SelfContactOptions tolerant = options();
    tolerant.ccd_depth_mm = 0.1;
    SelfContact thin(p.surface, tolerant, kStiffness, 0.1);
    thin.detect(p.x);
    Eigen::VectorXd above = p.x, in = p.x;
    for (int i = 16; i < 32; ++i) {
      above[3 * i + 2] = 0.01;
      in[3 * i + 2] = -0.08;
    }
    EXPECT_GE(thin.find_crossing(above, in), 0);
  }
  SelfContactOptions too_deep = options();
  too_deep.ccd_depth_mm = 2 * too_deep.contact_mm;
  EXPECT_THROW(SelfContact(make_plates(2, 1.0).surface, too_deep, kStiffness, kMaxDepth), Error);
}

// The lower plate of make_plates(5, 2.0) bent into a valley along x = 2 (z = slope |x - 2|) or a
// bowl around its node (2, 2) (z = slope x the distance from it): concave seen from outside (+z),
// so that a point just below the valley's floor has no face under it, only the floor's edges or
// its corner. One vertex of the upper plate (node 31) is put at `at`; the upper plate, 2 mm up,
// keeps its vertices only, so that node 31's pair is the only one.
Plates valley(bool bowl, const Eigen::Vector3d& at, double slope = 0.2) {
  Plates p = make_plates(5, 2.0);
  p.surface.triangles.resize(32);
  p.surface.triangle_plane.resize(32);
  p.surface.triangle_outward.resize(32);
  for (int id = 0; id < 25; ++id) {
    const double i = id % 5, j = id / 5;
    p.x[3 * id + 2] = slope * (bowl ? std::hypot(i - 2.0, j - 2.0) : std::abs(i - 2.0));
  }
  p.x.segment<3>(3 * 31) = at;
  return p;
}

const SelfContact::Pair* pair_of(const SelfContact& c, int vertex) {
  for (const SelfContact::Pair& pr : c.pairs())
    if (pr.vertex == vertex) return &pr;
  return nullptr;
}

// A vertex that has sunk in under a valley of the other surface, where its nearest point is on
// the valley's floor (an edge, or the bowl's corner), is inside: its distance is negative and the
// force pushes it out. The plain distance there (before) was positive, pushing it deeper, and
// jumped from -depth to +depth where the nearest point passed from a face onto the edge.
TEST(SelfContact, AVertexSunkUnderAValleyIsInsideAndPushedOut) {
  for (const bool bowl : {false, true}) {
    const Plates p = valley(bowl, {2.0, bowl ? 2.0 : 1.6, -0.02});
    SelfContact c(p.surface, options(), kStiffness, kMaxDepth);
    c.detect(p.x);
    ASSERT_EQ(c.pairs().size(), 1u);
    const SelfContact::Pair* pr = pair_of(c, 31);
    ASSERT_NE(pr, nullptr) << (bowl ? "bowl" : "valley");
    EXPECT_LT(pr->weights.minCoeff(), 1e-9) << "the nearest point is on an edge or a corner";
    EXPECT_NEAR(pr->distance, -0.02, 1e-12) << (bowl ? "bowl" : "valley");
    EXPECT_NEAR(pr->normal.z(), 1.0, 1e-12);
    Eigen::VectorXd f = Eigen::VectorXd::Zero(p.x.size()), v = f;
    c.add_forces(v, &f);
    EXPECT_GT(f[3 * 31 + 2], 0.0) << "pushed out, up";
    // The force is minus the energy's gradient there too (the pairs re-detected on each side).
    const double h = 1e-7;
    for (int k = 0; k < 3; ++k) {
      Eigen::VectorXd xp = p.x, xm = p.x, g = f;
      xp[3 * 31 + k] += h;
      xm[3 * 31 + k] -= h;
      SelfContact cp(p.surface, options(), kStiffness, kMaxDepth),
          cm(p.surface, options(), kStiffness, kMaxDepth);
      cp.detect(xp);
      cm.detect(xm);
      const double fd = -(cp.add_forces(v, &g) - cm.add_forces(v, &g)) / (2 * h);
      EXPECT_NEAR(fd, f[3 * 31 + k], 1e-6 * std::max(1.0, std::abs(f[3 * 31 + k]))) << k;
    }
  }
  // Swept across the valley at a fixed height below its floor: inside all the way, and the
  // distance as continuous as a distance is (it changes by no more than the vertex moves).
  double last = 0.0;
  for (int k = 0; k <= 200; ++k) {
    const double xk = 1.5 + k * 0.005;
    const Plates p = valley(false, {xk, 1.6, -0.02});
    SelfContact c(p.surface, options(), kStiffness, kMaxDepth);
    c.detect(p.x);
    const SelfContact::Pair* pr = pair_of(c, 31);
    ASSERT_NE(pr, nullptr) << xk;
    EXPECT_LT(pr->distance, 0.0) << "x = " << xk;
    if (k > 0) {
      EXPECT_LE(std::abs(pr->distance - last), 0.005 * (1 + 1e-9)) << "x = " << xk;
    }
    last = pr->distance;
  }
  // Outside, over the floor: positive, with the faces' own signs.
  {
    const Plates p = valley(false, {2.0, 1.6, 0.1});
    SelfContact c(p.surface, options(), kStiffness, kMaxDepth);
    c.detect(p.x);
    ASSERT_NE(pair_of(c, 31), nullptr);
    EXPECT_NEAR(pair_of(c, 31)->distance, 0.1 / std::sqrt(1.0 + 0.04), 1e-12);
  }
  // Beyond the surface's boundary (a plate's edge: the free edge of a leaflet) the outside
  // wraps around it: positive whatever the side.
  for (const double z : {-0.1, 0.1}) {
    const Plates p = valley(false, {4.3, 1.6, 0.4 + z});
    SelfContact c(p.surface, options(), kStiffness, kMaxDepth);
    c.detect(p.x);
    ASSERT_NE(pair_of(c, 31), nullptr);
    EXPECT_NEAR(pair_of(c, 31)->distance, std::hypot(0.3, z), 1e-12) << z;
  }
}

// A strip of the unrolled plane (u along it, v across; spacing 0.5 mm) folded in 3D into a U:
// the arms face each other `gap` mm apart, with random bumps of up to 0.08 mm. Vertices of one arm
// pair with triangles of the other where they are more than the exclusion distance apart along the
// strip; near the fold they are neighbours and excluded. `period` > 0 makes the plane periodic in u
// (the strip's two ends neighbours).
Plates make_fold(double gap, double period, unsigned seed) {
  const int nu = 41, nv = 9;
  const double h = 0.5, a = 8.0, R = 0.5 * gap;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> bump(-0.08, 0.08);
  Plates p;
  p.x.resize(3 * nu * nv);
  p.surface.plane.resize(nu * nv, 2);
  p.surface.period = period;
  const double pi = std::acos(-1.0);
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      const int id = j * nu + i;
      const double u = i * h;
      Eigen::Vector3d q;
      if (u < a) {
        q = {u, j * h, 0.0};
      } else if (u < a + pi * R) {
        const double t = (u - a) / R;
        q = {a + R * std::sin(t), j * h, R - R * std::cos(t)};
      } else {
        q = {a - (u - a - pi * R), j * h, 2.0 * R};
      }
      q.z() += bump(rng);
      p.x.segment<3>(3 * id) = q;
      p.surface.plane.row(id) = Eigen::RowVector2d(u, j * h);
      p.surface.vertices.push_back(id);
      p.surface.vertex_plane.push_back(id);
      p.surface.vertex_area.push_back(h * h);
    }
  }
  for (int j = 0; j + 1 < nv; ++j) {
    for (int i = 0; i + 1 < nu; ++i) {
      const int a0 = j * nu + i, b = a0 + 1, c = a0 + nu + 1, d = a0 + nu;
      for (const std::array<int, 3>& t : {std::array<int, 3>{a0, b, c}, {a0, c, d}}) {
        p.surface.triangles.push_back(t);
        p.surface.triangle_plane.push_back(t);
        // (b - a) x (c - a) is +z on the lower arm and -z on the upper one: towards the other
        // arm on both, the side a vertex comes from.
        p.surface.triangle_outward.push_back(1);
      }
    }
  }
  return p;
}

// The surface with its triangles in another order (each triangle keeps its plane corners and
// side).
SelfContact::Surface shuffled(SelfContact::Surface s, unsigned seed) {
  std::vector<size_t> order(s.triangles.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::shuffle(order.begin(), order.end(), std::mt19937(seed));
  SelfContact::Surface out = s;
  for (size_t k = 0; k < order.size(); ++k) {
    out.triangles[k] = s.triangles[order[k]];
    out.triangle_plane[k] = s.triangle_plane[order[k]];
    out.triangle_outward[k] = s.triangle_outward[order[k]];
  }
  return out;
}

// Each contact vertex's closest pairing distance, sorted by vertex: what the pairs must agree
// on whichever triangle a tie (a vertex over a shared edge) went to.
std::vector<std::pair<int, double>> vertex_distances(const SelfContact& c) {
  std::vector<std::pair<int, double>> out;
  for (const SelfContact::Pair& pr : c.pairs()) out.emplace_back(pr.vertex, pr.distance);
  std::sort(out.begin(), out.end());
  return out;
}

// The full search takes triangles in consecutive groups and decides most vertices per group (a
// box, a sphere, a plane exclusion test), then per triangle. Whatever the triangles' order (a
// shuffled surface's groups are scattered, so its group tests decide almost nothing) and however
// wide the Verlet margin (30 mm: every vertex is a candidate of every triangle it is not
// excluded from, a brute-force search), the same pairs are found.
TEST(SelfContact, SearchFindsTheSamePairsWhateverTheTriangleOrderAndMargin) {
  for (const double period : {0.0, 21.0}) {
    const Plates p = make_fold(0.5, period, 7);  // within the alarm distance
    SelfContactOptions wide = options();
    wide.margin_mm = 30.0;
    SelfContact grouped(p.surface, options(), kStiffness, kMaxDepth);
    SelfContact scattered(shuffled(p.surface, 11), options(), kStiffness, kMaxDepth);
    SelfContact brute(shuffled(p.surface, 13), wide, kStiffness, kMaxDepth);
    const int n = grouped.detect(p.x);
    // Both arms' vertices over the other arm beyond the exclusion distance: most of 2 x 9 x 9.
    EXPECT_GT(n, 100) << "period " << period;
    EXPECT_EQ(scattered.detect(p.x), n) << "period " << period;
    EXPECT_EQ(brute.detect(p.x), n) << "period " << period;
    const auto a = vertex_distances(grouped), b = vertex_distances(scattered),
               c = vertex_distances(brute);
    ASSERT_EQ(a.size(), b.size());
    ASSERT_EQ(a.size(), c.size());
    for (size_t k = 0; k < a.size(); ++k) {
      EXPECT_EQ(a[k].first, b[k].first);
      EXPECT_EQ(a[k].first, c[k].first);
      EXPECT_NEAR(a[k].second, b[k].second, 1e-12);
      EXPECT_NEAR(a[k].second, c[k].second, 1e-12);
    }
  }
}

// The Verlet list: arms 1.9 mm apart (beyond the alarm distance, within alarm + margin) move
// 0.7 mm towards each other, each node by less than margin / 2, so the candidates found before
// the motion are reused; they must hold every pair a search at the new positions would find.
TEST(SelfContact, ReusedCandidatesHoldEveryPairThatComesWithinTheAlarm) {
  const Plates p = make_fold(1.9, 0.0, 5);
  SelfContactOptions wide = options();
  wide.margin_mm = 30.0;
  SelfContact list(p.surface, options(), kStiffness, kMaxDepth);
  SelfContact brute(p.surface, wide, kStiffness, kMaxDepth);
  EXPECT_EQ(list.detect(p.x), 0);
  brute.detect(p.x);
  Eigen::VectorXd x = p.x;
  for (int i = 0; i < x.size(); i += 3) x[i + 2] += x[i + 2] > 0.95 ? -0.7 : 0.7;
  const int n = list.detect(x);
  EXPECT_EQ(list.reused(), 1);
  EXPECT_EQ(list.searches(), 1);
  EXPECT_GT(n, 50);
  EXPECT_EQ(brute.detect(x), n);
  const auto a = vertex_distances(list), b = vertex_distances(brute);
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].first, b[k].first);
    EXPECT_NEAR(a[k].second, b[k].second, 1e-12);
  }
}

TEST(SelfContact, BadOptions) {
  Plates p = make_plates(3, 1.0);
  SelfContactOptions o = options();
  o.alarm_mm = 0.2;
  o.contact_mm = 0.3;
  EXPECT_THROW(SelfContact(p.surface, o, kStiffness, kMaxDepth), Error);
  EXPECT_THROW(SelfContact(p.surface, options(), -1.0, kMaxDepth), Error);
  EXPECT_THROW(SelfContact(p.surface, options(), kStiffness, 0.0), Error);
  o = options();
  o.stiffness_factor = 0.5;  // below 1: the pressure would push vertices past the contact distance
  std::string why;
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find("stiffness factor"), std::string::npos) << why;
}

// The contact law with its wall below the contact distance: continuous force, stiffness equal
// to the force's derivative (finite differences) on every branch, growing to (1 + wall_factor)
// k at zero distance; nothing beyond the alarm distance.
TEST(SelfContact, WallLawIsC1AndItsStiffnessIsTheForceDerivative) {
  Plates p = make_plates(3, 1.0);
  SelfContactOptions o = options();
  o.wall_factor = 50.0;
  const SelfContact c(p.surface, o, kStiffness, kMaxDepth);
  const double k = 2.0;
  double f, kf, fp, kp, fm, km;
  for (double d : {0.7, 0.59, 0.45, 0.31, 0.3, 0.29, 0.1, 0.0, -0.2}) {
    c.law(d, k, &f, &kf);
    const double h = 1e-6;
    c.law(d + h, k, &fp, &kp);
    c.law(d - h, k, &fm, &km);
    // (at d = d_c the second derivative jumps: central differences are off by k_w h / (4 d_c))
    EXPECT_NEAR(kf, -(fp - fm) / (2 * h), 1e-3 * std::max(1.0, kf)) << "d " << d;
    EXPECT_NEAR(fp, fm, 1e-4 * std::max(1.0, f)) << "continuous at d " << d;
    EXPECT_GE(f, 0.0);
  }
  c.law(0.7, k, &f, &kf);
  EXPECT_EQ(f, 0.0);
  c.law(o.alarm_mm - 1e-9, k, &f, &kf);
  EXPECT_NEAR(f, 0.0, 1e-8);
  c.law(0.0, k, &f, &kf);
  EXPECT_NEAR(kf, k * (1 + o.wall_factor), 1e-12);
}

// The product with the contact tangent couples vertex and triangle; it equals the triplet
// matrix; the diagonal blocks are the triplet matrix's node-diagonal blocks; and forces are
// minus the energy gradient with the wall active (plates closer than the contact distance).
TEST(SelfContact, TangentProductDiagonalBlocksAndForcesAgree) {
  Plates p = make_plates(4, 0.2);
  SelfContactOptions o = options();
  o.wall_factor = 30.0;
  o.friction = 0.5;
  SelfContact c(p.surface, o, kStiffness, kMaxDepth);
  ASSERT_GT(c.detect(p.x), 0);
  Eigen::VectorXd v = Eigen::VectorXd::Zero(p.x.size());
  for (int i = 0; i < v.size(); ++i) v[i] = std::sin(1.3 * i);  // tangential slip: friction on
  Eigen::VectorXd f = Eigen::VectorXd::Zero(p.x.size());
  std::vector<Eigen::Triplet<double>> trip;
  c.add(v, &f, &trip, 0.7, 0.3);
  Eigen::SparseMatrix<double> K(p.x.size(), p.x.size());
  K.setFromTriplets(trip.begin(), trip.end());
  Eigen::VectorXd q(p.x.size());
  for (int i = 0; i < q.size(); ++i) q[i] = std::cos(0.7 * i);
  Eigen::VectorXd y = Eigen::VectorXd::Zero(q.size());
  c.multiply(q, 0.7, 0.3, &y);
  const Eigen::VectorXd Kq = K * q;
  ASSERT_GT(Kq.cwiseAbs().maxCoeff(), 0.0);
  EXPECT_LT((y - Kq).cwiseAbs().maxCoeff(), 1e-12 * Kq.cwiseAbs().maxCoeff());
  // Couplings matter: the diagonal blocks alone give a different product.
  const int nodes = static_cast<int>(p.x.size() / 3);
  SymmetricBlockMatrix D(std::vector<char>(nodes, 1), [&] {
    std::vector<std::vector<int>> single;
    for (int i = 0; i < nodes; ++i) single.push_back({i});
    return single;
  }());
  D.set_zero();
  c.add_diagonal_blocks(0.7, 0.3, &D);
  const Eigen::MatrixXd dense = Eigen::MatrixXd(K);
  for (int i = 0; i < nodes; ++i) {
    const Eigen::MatrixXd block = Eigen::MatrixXd(D.lower()).block<3, 3>(3 * i, 3 * i);
    const Eigen::Matrix3d ref = dense.block<3, 3>(3 * i, 3 * i);
    EXPECT_LT((Eigen::MatrixXd(block) - Eigen::MatrixXd(ref.triangularView<Eigen::Lower>()))
                  .cwiseAbs()
                  .maxCoeff(),
              1e-12 * std::max(1.0, dense.cwiseAbs().maxCoeff()));
  }
  Eigen::VectorXd yd;
  D.multiply(q, &yd);
  EXPECT_GT((yd - Kq).norm(), 1e-3 * Kq.norm());

  // Forces = -grad energy with the wall active (no friction for this check).
  o.friction = 0.0;
  SelfContact c0(p.surface, o, kStiffness, kMaxDepth);
  c0.detect(p.x);
  Eigen::VectorXd f0 = Eigen::VectorXd::Zero(p.x.size()), zero = f0;
  const double e0 = c0.add_forces(zero, &f0);
  ASSERT_GT(e0, 0.0);
  const double h = 1e-6;
  double worst = 0.0;
  for (int d = 0; d < p.x.size(); ++d) {
    Eigen::VectorXd xp = p.x, xm = p.x;
    xp[d] += h;
    xm[d] -= h;
    SelfContact cp(p.surface, o, kStiffness, kMaxDepth), cm(p.surface, o, kStiffness, kMaxDepth);
    cp.detect(xp);
    cm.detect(xm);
    Eigen::VectorXd g = zero;
    const double ep = cp.add_forces(zero, &g), em = cm.add_forces(zero, &g);
    worst = std::max(worst, std::abs(-(ep - em) / (2 * h) - f0[d]));
  }
  EXPECT_LT(worst, 1e-6 * std::max(1.0, f0.lpNorm<Eigen::Infinity>()));
}

// A load far above what the plain penalty holds within the contact distance: with the wall the
// pressed plate comes to rest outside the other plate, at the distance where the law balances
// the load (solved here by bisection); without it, it would rest through the other plate.
TEST(SelfContact, WallHoldsALoadThePenaltyAloneCannot) {
  Plates p = make_plates(5, 1.5, 0.0);
  SelfContactOptions o = options();
  o.wall_factor = 100.0;
  SelfContact c(p.surface, o, kStiffness, kMaxDepth);
  const double load = 0.1;  // N per vertex: the plain law would balance it at d = 0.6 - 1 mm
  ASSERT_LT(o.alarm_mm - load / (2.0 * kStiffness), 0.0);
  // Overdamped (terminal speed load / (damping mass) = 10 mm/s): a slow approach, as the
  // valve's stiffness-proportional damping makes it.
  const double dt = 1e-3, mass = 1e-6, damping = 1e4;
  Eigen::VectorXd x = p.x, v = Eigen::VectorXd::Zero(x.size());
  for (int step = 0; step < 6000; ++step) {
    c.detect(x);
    Eigen::VectorXd f = Eigen::VectorXd::Zero(x.size());
    std::vector<Eigen::Triplet<double>> trip;
    c.add(v, &f, &trip, dt * dt, dt);
    Eigen::VectorXd diag = Eigen::VectorXd::Constant(x.size(), mass * (1 + damping * dt));
    for (const auto& t : trip) {
      if (t.row() == t.col()) diag[t.row()] += t.value();
    }
    for (int i = 25; i < 50; ++i) {
      for (int k = 0; k < 3; ++k) {
        const int d = 3 * i + k;
        const double fd = f[d] - (k == 2 ? load : 0.0) - damping * mass * v[d];
        v[d] += dt * fd / diag[d];
      }
    }
    for (int i = 25; i < 50; ++i) x.segment<3>(3 * i) += dt * v.segment<3>(3 * i);
  }
  // Equilibrium of an interior vertex: its own pair and the lower plate's vertex under it push
  // with the same law (k = stiffness_per_area x 1 mm^2 each): 2 F(d) = load.
  double lo = -0.5, hi = o.alarm_mm;
  for (int it = 0; it < 100; ++it) {
    const double mid = 0.5 * (lo + hi);
    double f, k;
    c.law(mid, kStiffness, &f, &k);
    (2.0 * f > load ? lo : hi) = mid;
  }
  EXPECT_GT(lo, 0.0);
  const int centre = 25 + 2 * 5 + 2;
  EXPECT_NEAR(x[3 * centre + 2], lo, 0.02);
  for (int i = 25; i < 50; ++i) EXPECT_GT(x[3 * i + 2], 0.0) << "vertex " << i << " went through";
}

// The static solve's smooth distance (SelfContactOptions::smooth_mm): the kernel's mean of the
// other surface's face planes, so that the energy is smooth where the nearest face changes.
SelfContactOptions smooth_options() {
  SelfContactOptions o = options();
  o.smooth_mm = 1.5;
  return o;
}

// Energy, forces and (optionally) the exact stiffness of a smooth contact at x.
double smooth_forces(const SelfContact::Surface& surface, const Eigen::VectorXd& x,
                     Eigen::VectorXd* f, SelfContact* keep = nullptr) {
  SelfContact local(surface, smooth_options(), kStiffness, kMaxDepth);
  SelfContact& c = keep ? *keep : local;
  c.set_smooth(true);
  c.detect(x);
  f->setZero(x.size());
  return c.add_forces(Eigen::VectorXd::Zero(x.size()), f);
}

// Over a flat face the smooth distance is the plane's: a vertex of the upper plate over the
// lower one's interior feels the nearest-triangle law's force, whatever triangles its kernel
// holds. The forces are minus the energy's gradient (pairs found again on each side), and
// the energy does not change when the plates move or turn together: no net force, no net torque.
TEST(SmoothContact, IsExactOverAFlatFaceAndItsForceIsMinusTheEnergyGradient) {
  const Plates p = make_plates(9, 0.4, 0.37);
  Eigen::VectorXd f, f0;
  smooth_forces(p.surface, p.x, &f);
  SelfContact plain(p.surface, options(), kStiffness, kMaxDepth);
  plain.detect(p.x);
  f0.setZero(p.x.size());
  plain.add_forces(Eigen::VectorXd::Zero(p.x.size()), &f0);
  const int inner = 81 + 4 * 9 + 4;  // the upper plate's centre, far from the lower one's rim
  EXPECT_GT(f[3 * inner + 2], 0.0) << "pushed away from the lower plate (up)";
  Eigen::Vector3d net = Eigen::Vector3d::Zero(), torque = net;
  for (Eigen::Index i = 0; i < p.x.size() / 3; ++i) {
    net += f.segment<3>(3 * i);
    torque += Eigen::Vector3d(p.x.segment<3>(3 * i)).cross(Eigen::Vector3d(f.segment<3>(3 * i)));
  }
  EXPECT_LT(net.norm(), 1e-12 * f.norm() * p.x.size());
  EXPECT_LT(torque.norm(), 1e-11 * f.norm() * p.x.size());
  // The law's force at 0.4 mm with the vertex's area (1 mm^2), as the plain law gives it.
  EXPECT_NEAR(f[3 * inner + 2], f0[3 * inner + 2], 0.05 * f0[3 * inner + 2]);
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  Eigen::VectorXd e(p.x.size());
  for (Eigen::Index i = 0; i < e.size(); ++i) e[i] = n01(rng);
  const double h = 1e-6;
  Eigen::VectorXd g;
  const double fd =
      -(smooth_forces(p.surface, p.x + h * e, &g) - smooth_forces(p.surface, p.x - h * e, &g)) /
      (2 * h);
  EXPECT_NEAR(fd, f.dot(e), 1e-6 * std::abs(f.dot(e))) << "f . e against -dE/de";
}

// A vertex swept across a valley of the other surface (the crease where the static solve
// stalled): the nearest triangle's law turns the force by the angle between the faces at the
// valley's floor, the smooth one turns it gradually. Steps of 0.005 mm: the largest change of
// the sideways force per step is a small part of the plain law's jump.
TEST(SmoothContact, TheForceTurnsSmoothlyAcrossAValley) {
  double plain_jump = 0.0, smooth_step = 0.0, last_plain = 0.0, last_smooth = 0.0;
  for (int k = 0; k <= 120; ++k) {
    const double xk = 1.7 + k * 0.005;
    const Plates p = valley(false, {xk, 1.6, 0.35}, 0.3);
    Eigen::VectorXd fs, fp = Eigen::VectorXd::Zero(p.x.size());
    smooth_forces(p.surface, p.x, &fs);
    SelfContact plain(p.surface, options(), kStiffness, kMaxDepth);
    plain.detect(p.x);
    plain.add_forces(Eigen::VectorXd::Zero(p.x.size()), &fp);
    ASSERT_GT(fs[3 * 31 + 2], 0.0) << xk;
    if (k > 0) {
      plain_jump = std::max(plain_jump, std::abs(fp[3 * 31] - last_plain));
      smooth_step = std::max(smooth_step, std::abs(fs[3 * 31] - last_smooth));
    }
    last_plain = fp[3 * 31];
    last_smooth = fs[3 * 31];
  }
  std::printf(
      "  largest sideways force change per 0.005 mm: nearest triangle %.3g N, smooth %.3g N\n",
      plain_jump, smooth_step);
  EXPECT_GT(plain_jump, 0.0);
  EXPECT_LT(smooth_step, 0.05 * plain_jump);
}

// The exact stiffness of the smooth pairs (linearize_exact / multiply_exact) against central
// differences of the forces, along random directions, over a valley, a bowl and beyond a plate's
// rim (where the distance to the boundary's edges joins in).
TEST(SmoothContact, TheExactStiffnessIsTheForcesDerivative) {
  std::mt19937 rng(11);
  std::normal_distribution<double> n01;
  const std::vector<std::pair<bool, Eigen::Vector3d>> cases{
      {false, {2.0, 1.6, 0.3}}, {true, {2.1, 1.9, 0.25}}, {false, {4.25, 1.6, 0.45}}};
  for (const auto& [bowl, at] : cases) {
    const Plates p = valley(bowl, at, 0.3);
    SelfContact c(p.surface, smooth_options(), kStiffness, kMaxDepth);
    Eigen::VectorXd f;
    smooth_forces(p.surface, p.x, &f, &c);
    ASSERT_GT(f.norm(), 0.0) << at.transpose();
    c.linearize_exact(p.x);
    for (int trial = 0; trial < 3; ++trial) {
      Eigen::VectorXd e(p.x.size());
      for (Eigen::Index i = 0; i < e.size(); ++i) e[i] = n01(rng);
      Eigen::VectorXd Ke = Eigen::VectorXd::Zero(p.x.size()), fp, fm;
      c.multiply_exact(e, &Ke);
      const double h = 1e-6;
      smooth_forces(p.surface, p.x + h * e, &fp);
      smooth_forces(p.surface, p.x - h * e, &fm);
      const Eigen::VectorXd fd = -(fp - fm) / (2 * h);
      EXPECT_LT((Ke - fd).norm(), 1e-4 * Ke.norm())
          << "at " << at.transpose() << " trial " << trial;
    }
  }
}

// Beyond a plate's rim (the free edge of a leaflet) the outside wraps around: the smooth distance
// is positive below the face's plane as above it, and the vertex is pushed away from the rim.
TEST(SmoothContact, BeyondTheRimTheVertexIsOutside) {
  for (const double z : {-0.15, 0.15}) {
    const Plates p = valley(false, {4.2, 1.6, 0.44 + z}, 0.2);  // the face's plane: z = 0.44
    Eigen::VectorXd f;
    smooth_forces(p.surface, p.x, &f);
    EXPECT_GT(f[3 * 31], 0.0) << "pushed outwards, beyond the rim (z " << z << ")";
    EXPECT_GT(z * f[3 * 31 + 2], 0.0) << "and away from the plane's side it is on (z " << z << ")";
  }
}

}  // namespace
}  // namespace mvtwin::forward
