// The HEALPix environment (host/environment.cpp) and its importance sampler
// (host/env_sampler.cpp): the same tree descent, draw for draw.
#ifndef HT_ENVIRONMENT_GLSL
#define HT_ENVIRONMENT_GLSL

#include "bindings.glsl"
#include "healpix.glsl"
#include "rng.glsl"

vec3 envRadiance(uint pixel) {
  return scene.radiance[pixel >> HT_RADIANCE_CHUNK_SHIFT].v[pixel & ((1u << HT_RADIANCE_CHUNK_SHIFT) - 1u)];
}
float treeAvg(uint node) {
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

// pickWeighted<n> over the average tree's nodes first..first+n-1.
uint pickWeighted(uint first, uint n, float u, out float prob) {
  precise float sum = 0.0;
  for (uint i = 0u; i < n; ++i) sum += treeAvg(first + i);
  precise float target = u * sum;
  uint last = 0u;
  precise float acc = 0.0;
  for (uint i = 0u; i < n; ++i) {
    float w = treeAvg(first + i);
    if (w <= 0.0) continue;
    last = i;
    acc += w;
    if (target < acc) break;
  }
  precise float p = treeAvg(first + last) / sum;
  prob = p;
  return last;
}

struct EnvSample {
  vec3 dir;
  uint pixel;
  float pdf;  // solid-angle density
};

EnvSample sampleEnvironment(inout uint rng) {
  EnvSample s;
  if (scene.envHasLight == 0u) {
    s.dir = vec3(0.0, 1.0, 0.0);
    s.pixel = 0u;
    s.pdf = 0.0;
    return s;
  }
  float prob;
  uint node = pickWeighted(0u, 12u, rngNext(rng), prob);
  precise hreal p = hreal(prob);
  for (uint level = 1u; level <= scene.envOrder; ++level) {
    uint first = 4u * node;
    node = first + pickWeighted(levelOffset(level) + first, 4u, rngNext(rng), prob);
    p *= hreal(prob);
  }
  float dx = rngNext(rng);
  float dy = rngNext(rng);
  s.pixel = node;
  s.dir = envDirection(scene.envOrder, node, dx, dy);
  precise hreal pdf = p / envPixelSolidAngle();
  s.pdf = float(pdf);
  return s;
}

// environmentPixelProbability / pixel solid angle.
float environmentPdf(vec3 dir) {
  uint pixel = envPixelOf(dir);
  precise hreal p = 1.0;
  for (uint level = scene.envOrder; level >= 1u; --level) {
    uint first = levelOffset(level) + (pixel & ~3u);
    precise float sum = treeAvg(first) + treeAvg(first + 1u) + treeAvg(first + 2u) + treeAvg(first + 3u);
    float w = treeAvg(first + (pixel & 3u));
    if (w <= 0.0) return 0.0;
    precise float q = w / sum;
    p *= hreal(q);
    pixel >>= 2;
  }
  precise float sum = 0.0;
  for (uint f = 0u; f < 12u; ++f) sum += treeAvg(f);
  float top = treeAvg(pixel);
  if (!(top > 0.0)) return 0.0;
  precise float q = top / sum;
  precise hreal prob = p * hreal(q);
  precise hreal pdf = prob / envPixelSolidAngle();
  return float(pdf);
}

#endif
