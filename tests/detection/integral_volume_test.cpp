#include "mvtwin/detection/integral_volume.h"

#include <gtest/gtest.h>

#include "mvtwin/core/error.h"
#include "mvtwin/core/rng.h"

namespace mvtwin::detection {
namespace {

ImageVolume random_volume(std::uint64_t seed) {
  ImageVolume im;
  im.size = {9, 7, 6};
  Rng rng(seed);
  for (std::size_t i = 0; i < im.num_voxels(); ++i)
    im.data.push_back(static_cast<float>(rng.uniform(-5, 250)));
  return im;
}

/// Brute force over the box clipped to the volume.
double brute(const ImageVolume& im, Eigen::Vector3i lo, Eigen::Vector3i hi, bool squares,
             long* count) {
  double s = 0;
  *count = 0;
  for (int k = std::max(lo[2], 0); k < std::min(hi[2], im.size[2]); ++k)
    for (int j = std::max(lo[1], 0); j < std::min(hi[1], im.size[1]); ++j)
      for (int i = std::max(lo[0], 0); i < std::min(hi[0], im.size[0]); ++i) {
        const double v = im.at(i, j, k);
        s += squares ? v * v : v;
        ++*count;
      }
  return s;
}

TEST(IntegralVolume, BoxSumsEqualBruteForceSumsIncludingClippedBoxes) {
  const ImageVolume im = random_volume(3);
  const IntegralVolume iv(im);
  Rng rng(11);
  for (int t = 0; t < 2000; ++t) {
    Eigen::Vector3i lo, hi;
    for (int a = 0; a < 3; ++a) {
      lo[a] = rng.uniform_int(-3, im.size[a] + 1);
      hi[a] = lo[a] + rng.uniform_int(0, im.size[a] + 2);
    }
    long n = 0;
    const double s = brute(im, lo, hi, false, &n);
    ASSERT_NEAR(iv.sum(lo, hi), s, 1e-9 * std::max(1.0, std::abs(s)));
    ASSERT_NEAR(iv.sum_of_squares(lo, hi), brute(im, lo, hi, true, &n), 1e-6);
    ASSERT_NEAR(iv.mean(lo, hi), n ? s / n : 0.0, 1e-9);
  }
}

TEST(IntegralVolume, FeaturesEqualTheirDefinitionsAndRespondToASheet) {
  ImageVolume im;
  im.size = {21, 21, 21};
  im.data.assign(im.num_voxels(), 10.0f);
  for (int k = 0; k < 21; ++k)
    for (int j = 0; j < 21; ++j)
      im.data[static_cast<std::size_t>(10) + 21 * (j + 21 * static_cast<std::size_t>(k))] =
          200.0f;  // sheet x = 10
  const IntegralVolume iv(im);
  const std::vector<int> scales = {2, 4};
  std::vector<float> f(static_cast<std::size_t>(feature_count(scales)));
  voxel_features(iv, im, {10, 10, 10}, scales, f.data());
  // Scale 2: a 5^3 box holding one 25-voxel slab of 200 among 10s.
  long n = 0;
  const double m = brute(im, {8, 8, 8}, {13, 13, 13}, false, &n) / 125.0;
  EXPECT_NEAR(f[0], m, 1e-4);
  EXPECT_NEAR(f[0], (25 * 200.0 + 100 * 10.0) / 125.0, 1e-4);
  EXPECT_NEAR(f[2], 0.0, 1e-4) << "no edge across x at the sheet's centre";
  // Sheet feature across x: centre slab (x 9..11) mean minus outer slabs (x 8 and 12).
  EXPECT_NEAR(f[5], (200.0 + 2 * 10.0) / 3.0 - 10.0, 1e-4);
  EXPECT_NEAR(f[6], 0.0, 1e-4) << "nothing across y";
  EXPECT_NEAR(f.back(), 200.0f, 1e-6);
  // Beside the sheet, the edge feature along x sees it on one side only.
  voxel_features(iv, im, {12, 10, 10}, scales, f.data());
  EXPECT_LT(f[2], -10.0);
  EXPECT_THROW(IntegralVolume(ImageVolume{}), Error);
}

}  // namespace
}  // namespace mvtwin::detection
