#include "mvtwin/core/point_triangle_distance.h"

#include <algorithm>

namespace mvtwin {

Eigen::Vector3d closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                          const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;  // vertex region A

  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return b;  // vertex region B

  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {  // edge AB
    const double denom = d1 - d3;
    return denom > 0.0 ? Eigen::Vector3d(a + (d1 / denom) * ab) : a;
  }

  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return c;  // vertex region C

  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {  // edge AC
    const double denom = d2 - d6;
    return denom > 0.0 ? Eigen::Vector3d(a + (d2 / denom) * ac) : a;
  }

  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {  // edge BC
    const double denom = (d4 - d3) + (d5 - d6);
    return denom > 0.0 ? Eigen::Vector3d(b + ((d4 - d3) / denom) * (c - b)) : b;
  }

  const double sum = va + vb + vc;
  if (!(sum > 0.0)) {
    // Degenerate (collinear) triangle that fell through: the closest of the three edges.
    auto seg = [&](const Eigen::Vector3d& s0, const Eigen::Vector3d& s1) -> Eigen::Vector3d {
      const Eigen::Vector3d d = s1 - s0;
      const double l2 = d.squaredNorm();
      if (l2 <= 0.0) return s0;
      return s0 + std::clamp((p - s0).dot(d) / l2, 0.0, 1.0) * d;
    };
    Eigen::Vector3d best = seg(a, b);
    for (const Eigen::Vector3d& q : {seg(b, c), seg(c, a)}) {
      if ((q - p).squaredNorm() < (best - p).squaredNorm()) best = q;
    }
    return best;
  }
  const double denom = 1.0 / sum;
  return a + ab * (vb * denom) + ac * (vc * denom);  // face region
}

}  // namespace mvtwin
