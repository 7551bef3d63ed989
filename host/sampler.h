// Per-pixel sample points (shaders/sampler.glsl draws the same): sample i of
// the pixel's n gets one 2-D point per decision, the decisions numbered in
// the order the estimator makes them.
//
// Stratified: every decision (dimension) is its own Owen-scrambled Sobol'
// (0,2)-sequence, its sample order shuffled by a scramble of the index, so
// that dimensions do not correlate; the first 2^k points of every decision
// form a (0,k,2)-net. Independent: hashed i.i.d. points, the same warps.
// Every point is uniform on [0,1)^2 on its own, so no estimator gains bias;
// the seeds come from the pixel's stream, so neighbouring pixels decorrelate.
#pragma once

#include <cstdint>

#include <glm/vec2.hpp>

#include "rng.h"

namespace ht {

enum class SamplerKind : uint32_t { Independent = 0, Stratified = 1 };  // HT_SAMPLER_* in shaders/common.h

inline uint32_t reverseBits(uint32_t v) {
  v = ((v >> 1) & 0x55555555u) | ((v & 0x55555555u) << 1);
  v = ((v >> 2) & 0x33333333u) | ((v & 0x33333333u) << 2);
  v = ((v >> 4) & 0x0F0F0F0Fu) | ((v & 0x0F0F0F0Fu) << 4);
  v = ((v >> 8) & 0x00FF00FFu) | ((v & 0x00FF00FFu) << 8);
  return (v >> 16) | (v << 16);
}

// The first two dimensions of Sobol's sequence, bits reversed (digit k of
// the fraction is bit k): the first is the index itself (van der Corput);
// the second's generator matrix, for the primitive polynomial x + 1, is
// Pascal's triangle mod 2 (Kollig & Keller, "Efficient multidimensional
// sampling", 2002), so its digit r is the XOR of the index bits c that
// contain r (Lucas): a superset transform in five steps, with no loop.
inline uint32_t sobolSecondReversed(uint32_t i) {
  i ^= (i >> 1) & 0x55555555u;
  i ^= (i >> 2) & 0x33333333u;
  i ^= (i >> 4) & 0x0F0F0F0Fu;
  i ^= (i >> 8) & 0x00FF00FFu;
  i ^= (i >> 16) & 0x0000FFFFu;
  return i;
}

// Hash-based nested uniform (Owen) scramble of a binary fraction, on its
// bits reversed (digit k of the fraction is bit k): each digit is flipped by
// a function of the seed and of the digits above it, which keeps every
// elementary interval of a net an elementary interval (Laine & Karras 2011;
// Burley, "Practical Hash-based Owen Scrambling", JCGT 2020).
inline uint32_t owenScrambleReversed(uint32_t v, uint32_t seed) {
  v += seed;
  v ^= v * 0x6c50b47cu;
  v ^= v * 0xb82f1e52u;
  v ^= v * 0xc7afe638u;
  v ^= v * 0x8d22f6e6u;
  return v;
}
// The same on a fraction's bits. On an index (digits read from the top) it
// permutes every aligned block of 2^k indices onto an aligned block.
inline uint32_t owenScramble(uint32_t v, uint32_t seed) { return reverseBits(owenScrambleReversed(reverseBits(v), seed)); }

class PixelSampler {
 public:
  PixelSampler(SamplerKind kind, uint32_t pixelSeed) : kind_(kind), seed_(pixelSeed) {
    for (uint32_t k = 0; k < kCachedSeeds; ++k) seeds_[k] = hashedSeed(k);
  }

  // Sample `index` of the pixel; its first decision is dimension 0.
  void startSample(uint32_t index) {
    index_ = index;
    dimension_ = 0;
  }
  void setDimension(uint32_t dimension) { dimension_ = dimension; }

  // The next decision's point, 32 bits per coordinate.
  glm::uvec2 nextBits() {
    const uint32_t d = dimension_++;
    const uint32_t sx = seed(3 * d + 1), sy = seed(3 * d + 2);
    if (kind_ == SamplerKind::Independent) {
      const uint32_t i = pcgHash(index_);
      return {pcgHash(sx ^ i), pcgHash(sy ^ i)};
    }
    const uint32_t j = shuffled(d);
    return {reverseBits(owenScrambleReversed(j, sx)), reverseBits(owenScrambleReversed(sobolSecondReversed(j), sy))};
  }
  // The next decision's point drawn i.i.d. whatever the kind: for draws
  // that must be independent of the sample's other draws and gain nothing
  // from stratification (ris's reservoir).
  glm::vec2 getIndependent2D() {
    const uint32_t d = dimension_++;
    const uint32_t i = pcgHash(index_);
    return {float(pcgHash(seed(3 * d + 1) ^ i) >> 8) * 0x1p-24f, float(pcgHash(seed(3 * d + 2) ^ i) >> 8) * 0x1p-24f};
  }
  // In [0,1)^2 with 24 bits: for warps that use the point once.
  glm::vec2 get2D() {
    const glm::uvec2 b = nextBits();
    return {float(b.x >> 8) * 0x1p-24f, float(b.y >> 8) * 0x1p-24f};
  }
  // In [0,1)^2 with 53 bits (the point's 32, then 21 hashed from the index
  // and the dimension's seed): for hierarchical warps that rescale a
  // coordinate at every level.
  glm::dvec2 get2DPrecise() {
    const uint32_t s = seed(3 * dimension_);
    const glm::uvec2 b = nextBits();
    return {(double(b.x) * 0x1p21 + double(pcgHash(index_ ^ s) >> 11)) * 0x1p-53,
            (double(b.y) * 0x1p21 + double(pcgHash(index_ ^ ~s) >> 11)) * 0x1p-53};
  }

 private:
  // Seed k of the pixel: 3d for dimension d's index scramble, 3d + 1 and
  // 3d + 2 for its coordinates'. The first dimensions' are kept.
  static constexpr uint32_t kCachedSeeds = 12;
  uint32_t hashedSeed(uint32_t k) const { return pcgHash(seed_ + k * 0x9e3779b9u); }
  uint32_t seed(uint32_t k) const { return k < kCachedSeeds ? seeds_[k] : hashedSeed(k); }
  // The sample's index in dimension d's sequence: dimension 0 takes the
  // sample index itself, the others scramble it.
  uint32_t shuffled(uint32_t d) const { return d == 0 ? index_ : owenScramble(index_, seed(3 * d)); }

  SamplerKind kind_;
  uint32_t seed_;
  uint32_t seeds_[kCachedSeeds];
  uint32_t index_ = 0;
  uint32_t dimension_ = 0;
};

}  // namespace ht
