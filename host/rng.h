// Stateless, counter-based random numbers: the same (seed, stream) gives the
// same sequence on every thread and, later, in the shaders.
#pragma once

#include <cstdint>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace ht {

// PCG-RXS-M-XS 32-bit output permutation used as a hash (Jarzynski & Olano,
// "Hash Functions for GPU Rendering", JCGT 2020).
constexpr uint32_t pcgHash(uint32_t v) {
  uint32_t state = v * 747796405u + 2891336453u;
  uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

inline uint32_t hashCombine(uint32_t a, uint32_t b) { return pcgHash(a ^ pcgHash(b)); }

struct Rng {
  uint32_t state;

  Rng(uint32_t seed, uint32_t stream) : state(hashCombine(seed, stream)) {}

  uint32_t nextUint() {
    state = state * 747796405u + 2891336453u;
    uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
  }
  // Uniform in [0, 1): 24 random mantissa bits, never 1.
  float next() { return float(nextUint() >> 8) * 0x1p-24f; }
  // Several draws, x first: the order of a constructor's or a function's
  // arguments is unspecified, and the shaders must draw in the CPU's order.
  glm::vec2 next2() {
    const float x = next();
    const float y = next();
    return {x, y};
  }
  // Two uniforms in [0,1) with 53 bits each, x first: i.i.d. points for
  // the hierarchical warps (PixelSampler::get2DPrecise's counterpart).
  glm::dvec2 next2Precise() {
    const uint32_t xh = nextUint(), xl = nextUint(), yh = nextUint(), yl = nextUint();
    return {(double(xh) * 0x1p21 + double(xl >> 11)) * 0x1p-53, (double(yh) * 0x1p21 + double(yl >> 11)) * 0x1p-53};
  }
};

}  // namespace ht
