// The per-pixel sampler (host/sampler.h): nets, uniform marginals,
// decorrelated dimensions and pixels.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "chi2.h"
#include "rng.h"
#include "sampler.h"

using namespace ht;
using namespace ht::test;

namespace {

glm::uvec2 bitsAt(PixelSampler& s, uint32_t index, uint32_t dimension) {
  s.startSample(index);
  s.setDimension(dimension);
  return s.nextBits();
}

// Pixel seeds as the renderer draws them: the first draw of the pixel's stream.
uint32_t pixelSeed(uint32_t seed, uint32_t pixel) { return Rng(seed, pixel).nextUint(); }

}  // namespace

// Deterministic: for every dimension, the first 2^m points are a (0,m,2)-net
// (one point in every elementary interval of area 2^-m, whatever its shape),
// for any pixel seed; and so is every later aligned block of 2^m.
TEST(Sampler, StratifiedPointsAreNets) {
  for (uint32_t seed : {0u, 1u, 0x9e3779b9u, 0x7f4a7c15u}) {
    PixelSampler s(SamplerKind::Stratified, seed);
    for (uint32_t dimension : {0u, 1u, 2u, 7u, 31u}) {
      for (uint32_t m = 0; m <= 10; ++m) {
        for (uint32_t block : {0u, 3u}) {
          for (uint32_t bx = 0; bx <= m; ++bx) {
            const uint32_t by = m - bx;
            std::vector<int> hits(size_t(1) << m, 0);
            for (uint32_t i = 0; i < (1u << m); ++i) {
              const glm::uvec2 b = bitsAt(s, (block << m) + i, dimension);
              const uint32_t cx = bx == 0 ? 0 : b.x >> (32 - bx);
              const uint32_t cy = by == 0 ? 0 : b.y >> (32 - by);
              ++hits[(cy << bx) | cx];
            }
            ASSERT_EQ(*std::min_element(hits.begin(), hits.end()), 1)
                << "seed " << seed << " dimension " << dimension << " m " << m << " block " << block << " box " << bx
                << "x" << by;
          }
        }
      }
    }
  }
}

// The independent sampler is not stratified: among 64 points, some 8x8
// cells stay empty (a stratified set fills all of them).
TEST(Sampler, IndependentPointsAreNotNets) {
  int emptyCells = 0;
  for (uint32_t seed = 0; seed < 8; ++seed) {
    PixelSampler s(SamplerKind::Independent, seed);
    std::vector<int> hits(64, 0);
    for (uint32_t i = 0; i < 64; ++i) {
      const glm::uvec2 b = bitsAt(s, i, 0);
      ++hits[((b.y >> 29) << 3) | (b.x >> 29)];
    }
    emptyCells += int(std::count(hits.begin(), hits.end(), 0));
  }
  EXPECT_GT(emptyCells, 8 * 10);  // about 64 / e per set
}

// Points stay in [0,1)^2, and the precise ones agree with the 24-bit ones.
TEST(Sampler, PointsStayInTheUnitSquare) {
  for (SamplerKind kind : {SamplerKind::Stratified, SamplerKind::Independent}) {
    PixelSampler s(kind, 42);
    for (uint32_t i = 0; i < 4096; ++i) {
      for (uint32_t d = 0; d < 4; ++d) {
        s.startSample(i);
        s.setDimension(d);
        const glm::vec2 a = s.get2D();
        s.setDimension(d);
        const glm::dvec2 p = s.get2DPrecise();
        ASSERT_TRUE(a.x >= 0.0f && a.x < 1.0f && a.y >= 0.0f && a.y < 1.0f);
        ASSERT_TRUE(p.x >= 0.0 && p.x < 1.0 && p.y >= 0.0 && p.y < 1.0);
        ASSERT_EQ(double(a.x), std::floor(p.x * 0x1p24) * 0x1p-24);
        ASSERT_EQ(double(a.y), std::floor(p.y * 0x1p24) * 0x1p-24);
      }
    }
  }
}

// Each point on its own is uniform over pixels (what unbiasedness needs):
// chi-square of one coordinate of one (sample, dimension) across 20000
// pixel seeds, 64 bins, Sidak-corrected over every case.
TEST(Sampler, MarginalsAreUniform) {
  constexpr int kPixels = 20000, kBins = 64;
  const uint32_t indices[] = {0, 1, 5, 64, 1000};
  const uint32_t dimensions[] = {0, 1, 2, 9};
  const int tests = 2 * 2 * int(std::size(indices)) * int(std::size(dimensions));
  const double alpha = sidakAlpha(0.01, tests);
  const std::vector<double> expected(kBins, double(kPixels) / kBins);
  for (SamplerKind kind : {SamplerKind::Stratified, SamplerKind::Independent}) {
    for (uint32_t index : indices) {
      for (uint32_t dimension : dimensions) {
        std::vector<int> hx(kBins, 0), hy(kBins, 0);
        for (uint32_t p = 0; p < kPixels; ++p) {
          PixelSampler s(kind, pixelSeed(7, p));
          s.startSample(index);
          s.setDimension(dimension);
          const glm::dvec2 u = s.get2DPrecise();
          ++hx[size_t(u.x * kBins)];
          ++hy[size_t(u.y * kBins)];
        }
        for (const auto* h : {&hx, &hy}) {
          const Chi2Result r = chi2Test(*h, expected);
          EXPECT_GT(r.pValue, alpha) << "kind " << int(kind) << " index " << index << " dimension " << dimension
                                     << ": " << describe(r, *h, expected);
        }
      }
    }
  }
}

// Pearson correlation of two coordinates over many pairs; its z-score is
// about r sqrt(n) for independent coordinates.
struct Correlation {
  double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  int n = 0;
  void add(double x, double y) {
    sx += x;
    sy += y;
    sxx += x * x;
    syy += y * y;
    sxy += x * y;
    ++n;
  }
  double z() const {
    const double cov = sxy / n - (sx / n) * (sy / n);
    const double vx = sxx / n - (sx / n) * (sx / n), vy = syy / n - (sy / n) * (sy / n);
    return cov / std::sqrt(vx * vy) * std::sqrt(double(n));
  }
};

// Neighbouring pixels draw unrelated points: same sample and dimension in
// pixels p and p + 1 (and the row below, p + 256) do not correlate. Nor do
// two dimensions of one pixel. |z| < 4.5 for each of the few cases.
TEST(Sampler, PixelsAndDimensionsDecorrelate) {
  for (SamplerKind kind : {SamplerKind::Stratified, SamplerKind::Independent}) {
    for (uint32_t offset : {1u, 256u}) {
      Correlation c;
      for (uint32_t p = 0; p < 20000; ++p) {
        PixelSampler a(kind, pixelSeed(3, p)), b(kind, pixelSeed(3, p + offset));
        for (uint32_t i = 0; i < 4; ++i) c.add(bitsAt(a, i, 0).x * 0x1p-32, bitsAt(b, i, 0).x * 0x1p-32);
      }
      EXPECT_LT(std::abs(c.z()), 4.5) << "kind " << int(kind) << " pixel offset " << offset;
    }
    for (uint32_t d : {1u, 2u}) {
      Correlation c;
      for (uint32_t p = 0; p < 2000; ++p) {
        PixelSampler a(kind, pixelSeed(4, p));
        for (uint32_t i = 0; i < 64; ++i) c.add(bitsAt(a, i, 0).x * 0x1p-32, bitsAt(a, i, d).x * 0x1p-32);
      }
      EXPECT_LT(std::abs(c.z()), 4.5) << "kind " << int(kind) << " dimensions 0 and " << d;
    }
  }
}

// The scrambled index keeps the sample sets of the dimensions apart: the
// same sample index lands in different strata of dimension 0 and 1.
TEST(Sampler, DimensionsArePaddedNotCopied) {
  PixelSampler s(SamplerKind::Stratified, 9);
  int same = 0;
  for (uint32_t i = 0; i < 256; ++i) same += (bitsAt(s, i, 0).x >> 24) == (bitsAt(s, i, 1).x >> 24);
  EXPECT_LT(same, 8);
}
