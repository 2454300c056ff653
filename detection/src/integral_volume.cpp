#include "mvtwin/detection/integral_volume.h"

#include <algorithm>
#include <cmath>

#include "mvtwin/core/error.h"

namespace mvtwin::detection {

IntegralVolume::IntegralVolume(const ImageVolume& im) : size_(im.size) {
  if (im.data.size() != im.num_voxels() || im.num_voxels() == 0)
    throw Error("integral volume: the image is empty or its data does not match its size");
  const std::size_t nx = static_cast<std::size_t>(size_[0]) + 1,
                    ny = static_cast<std::size_t>(size_[1]) + 1,
                    nz = static_cast<std::size_t>(size_[2]) + 1;
  s_.assign(nx * ny * nz, 0.0);
  s2_.assign(s_.size(), 0.0);
  auto at = [&](std::size_t i, std::size_t j, std::size_t k) { return i + nx * (j + ny * k); };
  for (std::size_t k = 1; k < nz; ++k)
    for (std::size_t j = 1; j < ny; ++j)
      for (std::size_t i = 1; i < nx; ++i) {
        const double v =
            im.at(static_cast<int>(i - 1), static_cast<int>(j - 1), static_cast<int>(k - 1));
        // Inclusion-exclusion over the 7 smaller prefixes.
        const std::size_t c = at(i, j, k);
        const std::size_t x = at(i - 1, j, k), y = at(i, j - 1, k), z = at(i, j, k - 1);
        const std::size_t xy = at(i - 1, j - 1, k), xz = at(i - 1, j, k - 1),
                          yz = at(i, j - 1, k - 1);
        const std::size_t xyz = at(i - 1, j - 1, k - 1);
        s_[c] = v + s_[x] + s_[y] + s_[z] - s_[xy] - s_[xz] - s_[yz] + s_[xyz];
        s2_[c] = v * v + s2_[x] + s2_[y] + s2_[z] - s2_[xy] - s2_[xz] - s2_[yz] + s2_[xyz];
      }
}

double IntegralVolume::lookup(const std::vector<double>& t, Eigen::Vector3i lo,
                              Eigen::Vector3i hi) const {
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::clamp(lo[a], 0, size_[a]);
    hi[a] = std::clamp(hi[a], 0, size_[a]);
    if (hi[a] <= lo[a]) return 0.0;
  }
  const std::size_t nx = static_cast<std::size_t>(size_[0]) + 1,
                    ny = static_cast<std::size_t>(size_[1]) + 1;
  auto T = [&](int i, int j, int k) {
    return t[static_cast<std::size_t>(i) +
             nx * (static_cast<std::size_t>(j) + ny * static_cast<std::size_t>(k))];
  };
  return T(hi[0], hi[1], hi[2]) - T(lo[0], hi[1], hi[2]) - T(hi[0], lo[1], hi[2]) -
         T(hi[0], hi[1], lo[2]) + T(lo[0], lo[1], hi[2]) + T(lo[0], hi[1], lo[2]) +
         T(hi[0], lo[1], lo[2]) - T(lo[0], lo[1], lo[2]);
}

double IntegralVolume::sum(const Eigen::Vector3i& lo, const Eigen::Vector3i& hi) const {
  return lookup(s_, lo, hi);
}

double IntegralVolume::sum_of_squares(const Eigen::Vector3i& lo, const Eigen::Vector3i& hi) const {
  return lookup(s2_, lo, hi);
}

double IntegralVolume::mean(const Eigen::Vector3i& lo, const Eigen::Vector3i& hi) const {
  long n = 1;
  for (int a = 0; a < 3; ++a) n *= std::max(0, std::min(hi[a], size_[a]) - std::max(lo[a], 0));
  return n > 0 ? sum(lo, hi) / static_cast<double>(n) : 0.0;
}

int feature_count(const std::vector<int>& scales) {
  return kFeaturesPerScale * static_cast<int>(scales.size()) + 1;
}

void voxel_features(const IntegralVolume& iv, const ImageVolume& im, const Eigen::Vector3i& p,
                    const std::vector<int>& scales, float* out) {
  int f = 0;
  for (int r : scales) {
    const Eigen::Vector3i R = Eigen::Vector3i::Constant(r);
    const Eigen::Vector3i lo = p - R, hi = p + R + Eigen::Vector3i::Ones();
    const double m = iv.mean(lo, hi);
    long n = 1;
    for (int a = 0; a < 3; ++a)
      n *= std::max(0, std::min(hi[a], iv.size()[a]) - std::max(lo[a], 0));
    const double var = n > 0 ? iv.sum_of_squares(lo, hi) / static_cast<double>(n) - m * m : 0.0;
    out[f++] = static_cast<float>(m);
    out[f++] = static_cast<float>(std::sqrt(std::max(0.0, var)));
    for (int a = 0; a < 3; ++a) {
      // Edge: the half-box after p minus the half-box before it, along axis a.
      Eigen::Vector3i alo = lo, ahi = hi, blo = lo, bhi = hi;
      ahi[a] = p[a];
      blo[a] = p[a] + 1;
      out[f++] = static_cast<float>(iv.mean(blo, bhi) - iv.mean(alo, ahi));
    }
    for (int a = 0; a < 3; ++a) {
      // Thin sheet across axis a: the central slab (3 voxels) minus the two outer slabs.
      Eigen::Vector3i clo = lo, chi = hi;
      clo[a] = p[a] - 1;
      chi[a] = p[a] + 2;
      Eigen::Vector3i olo = lo, ohi = hi, ulo = lo, uhi = hi;
      ohi[a] = p[a] - 1;
      ulo[a] = p[a] + 2;
      out[f++] =
          static_cast<float>(iv.mean(clo, chi) - 0.5 * (iv.mean(olo, ohi) + iv.mean(ulo, uhi)));
    }
    // Centre (half-width r/2) minus the whole box.
    const Eigen::Vector3i h = Eigen::Vector3i::Constant(std::max(1, r / 2));
    out[f++] = static_cast<float>(iv.mean(p - h, p + h + Eigen::Vector3i::Ones()) - m);
  }
  const bool inside =
      (p.array() >= 0).all() && p[0] < im.size[0] && p[1] < im.size[1] && p[2] < im.size[2];
  out[f++] = inside ? im.at(p[0], p[1], p[2]) : 0.0f;
}

}  // namespace mvtwin::detection
