#include <Eigen/Geometry>

#include "mvtwin/core/leaflet_grid.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "mvtwin/core/error.h"

namespace mvtwin {
namespace {

// Catmull-Rom weights for the segment between p1 and p2 at parameter f in [0,1]; they sum to
// one and give p1 at f=0 and p2 at f=1, so grid points are reproduced exactly.
Eigen::Vector4d catmull_rom_weights(double f) {
  const double f2 = f * f, f3 = f2 * f;
  return {-0.5 * f3 + f2 - 0.5 * f, 1.5 * f3 - 2.5 * f2 + 1.0, -1.5 * f3 + 2.0 * f2 + 0.5 * f,
          0.5 * f3 - 0.5 * f2};
}

}  // namespace

LeafletGrid::LeafletGrid(int ures, int vres, Points points)
    : ures_(ures), vres_(vres), points_(std::move(points)) {
  if (ures < 8 || ures % 2 != 0) {
    throw Error("leaflet grid: ures must be even and at least 8 (got " + std::to_string(ures) +
                ")");
  }
  if (vres < 3) {
    throw Error("leaflet grid: vres must be at least 3 (got " + std::to_string(vres) + ")");
  }
  if (points_.rows() != static_cast<Eigen::Index>(ures) * vres) {
    throw Error("leaflet grid: expected ures*vres = " + std::to_string(ures * vres) +
                " points, got " + std::to_string(points_.rows()));
  }
}

Eigen::Vector3d LeafletGrid::at(int u, int v) const {
  u = ((u % ures_) + ures_) % ures_;
  return points_.row(static_cast<Eigen::Index>(v) * ures_ + u).transpose();
}

Eigen::Vector3d LeafletGrid::sample(double s, double t) const {
  const double x = (s - std::floor(s)) * ures_;
  const int i = static_cast<int>(std::floor(x));
  const Eigen::Vector4d wu = catmull_rom_weights(x - i);

  const double y = std::clamp(t, 0.0, 1.0) * (vres_ - 1);
  int j = std::min(static_cast<int>(std::floor(y)), vres_ - 2);
  const Eigen::Vector4d wv = catmull_rom_weights(y - j);

  // Row j+k of column u, with linear extrapolation beyond the annulus and the free edge.
  auto row_point = [&](int u, int jj) -> Eigen::Vector3d {
    if (jj < 0) return 2.0 * at(u, 0) - at(u, 1);
    if (jj > vres_ - 1) return 2.0 * at(u, vres_ - 1) - at(u, vres_ - 2);
    return at(u, jj);
  };
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int a = 0; a < 4; ++a) {
    Eigen::Vector3d col = Eigen::Vector3d::Zero();
    for (int b = 0; b < 4; ++b) col += wv[b] * row_point(i - 1 + a, j - 1 + b);
    p += wu[a] * col;
  }
  return p;
}

LeafletGrid LeafletGrid::resampled(int ures, int vres) const {
  Points p(static_cast<Eigen::Index>(ures) * vres, 3);
  for (int v = 0; v < vres; ++v) {
    for (int u = 0; u < ures; ++u) {
      p.row(static_cast<Eigen::Index>(v) * ures + u) =
          sample(static_cast<double>(u) / ures, static_cast<double>(v) / (vres - 1)).transpose();
    }
  }
  return LeafletGrid(ures, vres, std::move(p));
}

TriangleMesh LeafletGrid::triangulate() const {
  TriangleMesh m;
  m.V = points_;
  m.F.resize(2 * static_cast<Eigen::Index>(ures_) * (vres_ - 1), 3);
  Eigen::Index f = 0;
  for (int v = 0; v + 1 < vres_; ++v) {
    for (int u = 0; u < ures_; ++u) {
      const int un = (u + 1) % ures_;
      const int a = v * ures_ + u, b = v * ures_ + un;
      const int c = (v + 1) * ures_ + un, d = (v + 1) * ures_ + u;
      m.F.row(f++) << a, b, c;
      m.F.row(f++) << a, c, d;
    }
  }
  return m;
}

LeafletTag LeafletGrid::column_tag(int u) const {
  u = ((u % ures_) + ures_) % ures_;
  return u < ures_ / 2 ? LeafletTag::kAnterior : LeafletTag::kPosterior;
}

Eigen::VectorXi LeafletGrid::triangle_tags() const {
  Eigen::VectorXi tags(2 * ures_ * (vres_ - 1));
  int f = 0;
  for (int v = 0; v + 1 < vres_; ++v) {
    for (int u = 0; u < ures_; ++u) {
      const int t = static_cast<int>(column_tag(u));
      tags[f++] = t;
      tags[f++] = t;
    }
  }
  return tags;
}

double LeafletGrid::radial_length(int u) const {
  double len = 0.0;
  for (int v = 0; v + 1 < vres_; ++v) len += (at(u, v + 1) - at(u, v)).norm();
  return len;
}

double LeafletGrid::radial_length_at(double s) const {
  constexpr int kSteps = 200;
  double len = 0.0;
  Eigen::Vector3d prev = sample(s, 0.0);
  for (int k = 1; k <= kSteps; ++k) {
    const Eigen::Vector3d p = sample(s, static_cast<double>(k) / kSteps);
    len += (p - prev).norm();
    prev = p;
  }
  return len;
}

}  // namespace mvtwin
