// What every method's shader shares at a shading point: f cos V for a
// direction (host/shading.h), the BRDF and environment draws, and the
// accumulator type of a pixel's sum.
#ifndef HT_SHADING_GLSL
#define HT_SHADING_GLSL

#include "common.h"
#include "bindings.glsl"
#include "bsdf.glsl"
#include "environment.glsl"
#include "sampler.glsl"
#include "scene.glsl"

#if HT_FP64
#define accvec3 dvec3
#else
#define accvec3 vec3
#endif

// Sums and reals kept between batches as their bits (GpuPixelState).
#if HT_FP64
accvec3 sumFromBits(uint64_t b[3]) {
  return accvec3(uint64BitsToDouble(b[0]), uint64BitsToDouble(b[1]), uint64BitsToDouble(b[2]));
}
void sumToBits(accvec3 v, out uint64_t b[3]) {
  b[0] = doubleBitsToUint64(v.x);
  b[1] = doubleBitsToUint64(v.y);
  b[2] = doubleBitsToUint64(v.z);
}
hreal hrealFromBits(uint64_t b) { return uint64BitsToDouble(b); }
uint64_t hrealToBits(hreal v) { return doubleBitsToUint64(v); }
#else
accvec3 sumFromBits(uint64_t b[3]) {
  return accvec3(uintBitsToFloat(uint(b[0])), uintBitsToFloat(uint(b[1])), uintBitsToFloat(uint(b[2])));
}
void sumToBits(accvec3 v, out uint64_t b[3]) {
  b[0] = uint64_t(floatBitsToUint(v.x));
  b[1] = uint64_t(floatBitsToUint(v.y));
  b[2] = uint64_t(floatBitsToUint(v.z));
}
hreal hrealFromBits(uint64_t b) { return uintBitsToFloat(uint(b)); }
uint64_t hrealToBits(hreal v) { return uint64_t(floatBitsToUint(v)); }
#endif

struct Shading {
  Frame frame;
  vec3 woLocal;
  vec3 origin;
  GpuMaterial material;
};
uint gShadowRays = 0u;

// f cos V for a direction whose radiance is already known (Shading::reflected).
precise vec3 reflected(Shading sh, vec3 wi, vec3 radiance) {
  if (radiance == vec3(0.0)) return vec3(0.0);
  precise vec3 fcos = evalBsdf(sh.material, sh.woLocal, toLocal(sh.frame, wi));
  if (fcos == vec3(0.0)) return fcos;
  ++gShadowRays;
  return occluded(sh.origin, wi) ? vec3(0.0) : fcos * radiance;
}

precise float powerHeuristic(float a, float b) {
  precise float a2 = a * a;
  precise float b2 = b * b;
  return a2 / (a2 + b2);
}

precise vec3 bsdfDirection(Shading sh, inout Sampler smp, out float pdf) {
  precise vec3 local = sampleBsdf(sh.material, sh.woLocal, samplerNext2D(smp));
  pdf = bsdfPdf(sh.material, sh.woLocal, local);
  return toWorld(sh.frame, local);
}

EnvSample sampleEnvironmentAt(inout Sampler smp) {
#if HT_FP64
  dvec2 u = samplerNext2DPrecise(smp);
#else
  vec2 u = samplerNext2DPrecise(smp);
#endif
  return sampleEnvironment(u.x, u.y);
}

#endif
