// host/sampler.h in GLSL: the same points for the same pixel seed, sample
// index and dimension.
#ifndef HT_SAMPLER_GLSL
#define HT_SAMPLER_GLSL

#include "common.h"
#include "rng.glsl"

struct Sampler {
  uint kind;  // HT_SAMPLER_*
  uint seed;  // the pixel's
  uint index;
  uint dimension;
};

Sampler samplerInit(uint kind, uint pixelSeed) { return Sampler(kind, pixelSeed, 0u, 0u); }
void samplerStart(inout Sampler s, uint index) {
  s.index = index;
  s.dimension = 0u;
}

// sampler.h's sobolSecondReversed and owenScrambleReversed.
uint sobolSecondReversed(uint i) {
  i ^= (i >> 1) & 0x55555555u;
  i ^= (i >> 2) & 0x33333333u;
  i ^= (i >> 4) & 0x0F0F0F0Fu;
  i ^= (i >> 8) & 0x00FF00FFu;
  i ^= (i >> 16) & 0x0000FFFFu;
  return i;
}

uint owenScrambleReversed(uint v, uint seed) {
  v += seed;
  v ^= v * 0x6c50b47cu;
  v ^= v * 0xb82f1e52u;
  v ^= v * 0xc7afe638u;
  v ^= v * 0x8d22f6e6u;
  return v;
}

uint samplerSeed(Sampler s, uint k) { return pcgHash(s.seed + k * 0x9e3779b9u); }

uint samplerShuffled(Sampler s, uint d) {
  if (d == 0u) return s.index;
  return bitfieldReverse(owenScrambleReversed(bitfieldReverse(s.index), samplerSeed(s, 3u * d)));
}

// PixelSampler::nextBits.
uvec2 samplerNextBits(inout Sampler s) {
  uint d = s.dimension++;
  uint sx = samplerSeed(s, 3u * d + 1u), sy = samplerSeed(s, 3u * d + 2u);
  if (s.kind == HT_SAMPLER_INDEPENDENT) {
    uint i = pcgHash(s.index);
    return uvec2(pcgHash(sx ^ i), pcgHash(sy ^ i));
  }
  uint j = samplerShuffled(s, d);
  return uvec2(bitfieldReverse(owenScrambleReversed(j, sx)),
               bitfieldReverse(owenScrambleReversed(sobolSecondReversed(j), sy)));
}

// PixelSampler::getIndependent2D.
precise vec2 samplerNextIndependent2D(inout Sampler s) {
  uint d = s.dimension++;
  uint i = pcgHash(s.index);
  const float kTwoPowMinus24 = uintBitsToFloat(0x33800000u);
  precise vec2 u = vec2(float(pcgHash(samplerSeed(s, 3u * d + 1u) ^ i) >> 8),
                        float(pcgHash(samplerSeed(s, 3u * d + 2u) ^ i) >> 8)) * kTwoPowMinus24;
  return u;
}

precise vec2 samplerNext2D(inout Sampler s) {
  uvec2 b = samplerNextBits(s);
  const float kTwoPowMinus24 = uintBitsToFloat(0x33800000u);
  precise vec2 u = vec2(float(b.x >> 8), float(b.y >> 8)) * kTwoPowMinus24;
  return u;
}

#if HT_FP64
// PixelSampler::get2DPrecise: 53 bits.
dvec2 samplerNext2DPrecise(inout Sampler s) {
  uint seed = samplerSeed(s, 3u * s.dimension);
  uvec2 b = samplerNextBits(s);
  const double kTwoPow21 = 2097152.0lf;
  const double kTwoPowMinus53 = packDouble2x32(uvec2(0u, 0x3CA00000u));
  precise double x = (double(b.x) * kTwoPow21 + double(pcgHash(s.index ^ seed) >> 11)) * kTwoPowMinus53;
  precise double y = (double(b.y) * kTwoPow21 + double(pcgHash(s.index ^ ~seed) >> 11)) * kTwoPowMinus53;
  return dvec2(x, y);
}
#else
// Without doubles: the sequence's top 24 bits.
vec2 samplerNext2DPrecise(inout Sampler s) { return samplerNext2D(s); }
#endif

#endif
