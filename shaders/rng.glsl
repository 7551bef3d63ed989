// host/rng.h in GLSL: the same (seed, stream) gives the same sequence.
#ifndef HT_RNG_GLSL
#define HT_RNG_GLSL

uint pcgHash(uint v) {
  uint state = v * 747796405u + 2891336453u;
  uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

uint hashCombine(uint a, uint b) { return pcgHash(a ^ pcgHash(b)); }

// Rng(seed, stream): the state is one uint.
uint rngInit(uint seed, uint stream) { return hashCombine(seed, stream); }

uint rngNextUint(inout uint state) {
  state = state * 747796405u + 2891336453u;
  uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

// Uniform in [0, 1): 24 random mantissa bits (exact, no rounding).
precise float rngNext(inout uint state) { return float(rngNextUint(state) >> 8) * uintBitsToFloat(0x33800000u); }

#endif
