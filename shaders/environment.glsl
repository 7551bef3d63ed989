// The HEALPix environment (host/environment.cpp) and its importance sampler
// (host/env_sampler.cpp): the same tree descent, draw for draw.
#ifndef HT_ENVIRONMENT_GLSL
#define HT_ENVIRONMENT_GLSL

#include "bindings.glsl"
#include "healpix.glsl"

vec3 envRadiance(uint pixel) {
  if (kTexels) return texelVec3(radianceTexels, pixel);
  return scene.radiance[pixel >> HT_RADIANCE_CHUNK_SHIFT].v[pixel & ((1u << HT_RADIANCE_CHUNK_SHIFT) - 1u)];
}
float treeAvg(uint node) {
  if (kTexels) return texelFetch(treeAvgTexels, int(node)).x;
  return scene.treeAvg[node >> HT_TREE_CHUNK_SHIFT].v[node & ((1u << HT_TREE_CHUNK_SHIFT) - 1u)];
}
uint levelOffset(uint level) { return 4u * ((1u << (2u * level)) - 1u); }

hreal envPixelSolidAngle() {
#if HT_FP64
  return packDouble2x32(scene.envPixelSolidAngleBits);
#else
  return scene.envPixelSolidAngle;
#endif
}

// Environment::toHealpixFrame: world (y-up) -> HEALPix frame, yaw undone.
hvec3 toHealpixFrame(vec3 w) {
  precise hreal c = hreal(scene.envCosYaw), s = hreal(scene.envSinYaw);
  precise hreal x = c * hreal(w.x) - s * hreal(w.z);
  precise hreal z = s * hreal(w.x) + c * hreal(w.z);
  return hvec3(z, x, hreal(w.y));
}
// Environment::fromHealpixFrame.
vec3 fromHealpixFrame(hvec3 h) {
  precise hreal c = hreal(scene.envCosYaw), s = hreal(scene.envSinYaw);
  precise hreal x = c * h.y + s * h.x;
  precise hreal z = -s * h.y + c * h.x;
  return vec3(float(x), float(h.z), float(z));
}

uint envPixelOf(vec3 worldDir) { return vecToPix(scene.envOrder, toHealpixFrame(worldDir)); }
vec3 envEval(vec3 worldDir) { return envRadiance(envPixelOf(worldDir)); }
vec3 envDirection(uint level, uint pix, float dx, float dy) { return fromHealpixFrame(pixToVec(level, pix, dx, dy)); }

#if HT_FP64
#define kEnvBelowOne packDouble2x32(uvec2(0xFFFFFFFFu, 0x3FEFFFFFu))  // 1 - 2^-53
#else
#define kEnvBelowOne uintBitsToFloat(0x3f7fffffu)
#endif

// pickRescaled<n> (host/env_sampler.cpp) over the average tree's nodes
// first..first+n-1.
uint pickRescaled(uint first, uint n, inout hreal u, out float prob) {
  precise float sum = 0.0;
  for (uint i = 0u; i < n; ++i) sum += treeAvg(first + i);
  precise hreal target = u * hreal(sum);
  uint last = 0u;
  precise hreal before = 0.0;
  precise hreal acc = 0.0;
  for (uint i = 0u; i < n; ++i) {
    float w = treeAvg(first + i);
    if (w <= 0.0) continue;
    last = i;
    before = acc;
    acc += hreal(w);
    if (target < acc) break;
  }
  float w = treeAvg(first + last);
  precise float p = w / sum;
  prob = p;
  precise hreal v = (target - before) / hreal(w);
  u = clamp(v, hreal(0.0), kEnvBelowOne);
  return last;
}

struct EnvSample {
  vec3 dir;
  uint pixel;
  float pdf;  // solid-angle density
};

// descendFrom (host/env_sampler.cpp): below node `node` of `level`, drawn
// with probability p, a child in four by the average tree at each level,
// then the point inside the leaf.
EnvSample envDescendFrom(uint level, uint node, hreal p, hreal x, hreal uy) {
  precise hreal q = p;
  for (uint l = level + 1u; l <= scene.envOrder; ++l) {
    float prob;
    uint first = 4u * node;
    node = first + pickRescaled(levelOffset(l) + first, 4u, x, prob);
    q *= hreal(prob);
  }
  const float kBelowOneF = uintBitsToFloat(0x3f7fffffu);
  EnvSample s;
  s.pixel = node;
  s.dir = envDirection(scene.envOrder, node, min(float(x), kBelowOneF), min(float(uy), kBelowOneF));
  precise hreal pdf = q / envPixelSolidAngle();
  s.pdf = float(pdf);
  return s;
}

EnvSample envNoSample() {
  EnvSample s;
  s.dir = vec3(0.0, 1.0, 0.0);
  s.pixel = 0u;
  s.pdf = 0.0;
  return s;
}

EnvSample sampleEnvironment(hreal ux, hreal uy) {
  if (scene.envHasLight == 0u) return envNoSample();
  hreal x = ux;
  float prob;
  uint face = pickRescaled(0u, 12u, x, prob);
  return envDescendFrom(0u, face, hreal(prob), x, uy);
}

// sampleEnvironmentBelow: below node `node` of `level`, by the average tree.
EnvSample sampleEnvironmentBelow(uint level, uint node, hreal ux, hreal uy) {
  if (!(treeAvg(levelOffset(level) + node) > 0.0)) return envNoSample();
  return envDescendFrom(level, node, hreal(1.0), ux, uy);
}

// environmentPixelProbabilityBelow: a leaf's probability inside its
// ancestor of `level`.
hreal environmentPixelProbabilityBelow(uint level, uint pixel) {
  precise hreal p = 1.0;
  for (uint l = scene.envOrder; l > level; --l) {
    uint first = levelOffset(l) + (pixel & ~3u);
    precise float sum = treeAvg(first) + treeAvg(first + 1u) + treeAvg(first + 2u) + treeAvg(first + 3u);
    float w = treeAvg(first + (pixel & 3u));
    if (w <= 0.0) return 0.0;
    precise float q = w / sum;
    p *= hreal(q);
    pixel >>= 2;
  }
  return p;
}

// environmentPixelProbability / pixel solid angle.
float environmentPdf(vec3 dir) {
  uint pixel = envPixelOf(dir);
  hreal p = environmentPixelProbabilityBelow(0u, pixel);
  if (p == 0.0) return 0.0;
  uint face = pixel >> (2u * scene.envOrder);
  precise float sum = 0.0;
  for (uint f = 0u; f < 12u; ++f) sum += treeAvg(f);
  float top = treeAvg(face);
  if (!(top > 0.0)) return 0.0;
  precise float q = top / sum;
  precise hreal prob = p * hreal(q);
  precise hreal pdf = prob / envPixelSolidAngle();
  return float(pdf);
}

#endif
