// The methods of the CPU reference renderer (host/render.cpp,
// host/integrator.cpp): the baselines here, the HT family (ht.glsl) and
// wis, tsis, ris (competitors.glsl); one invocation per pixel of the current
// tile, with the same random numbers.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require

#include "common.h"
#include "bindings.glsl"
#include "bsdf.glsl"
#include "environment.glsl"
#include "sampler.glsl"
#include "scene.glsl"

layout(local_size_x = HT_WORKGROUP_SIZE, local_size_y = HT_WORKGROUP_SIZE) in;

// The method as a specialization constant (HT_METHOD_*; HT_METHOD_ANY: the
// push constant's): lavapipe compiles every branch of the shader, so each
// method gets a pipeline that holds its own code only.
layout(constant_id = HT_SPEC_METHOD) const uint kSpecializedMethod = HT_METHOD_ANY;

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

#if HT_FP64
#define accvec3 dvec3
#else
#define accvec3 vec3
#endif

#include "competitors.glsl"
#include "ht.glsl"

// estimateDirect for the baseline methods, samples [begin, end).
uint baselineSamples(Shading sh, uint method, uint begin, uint end, inout Sampler smp, inout accvec3 sum,
                     inout uint directions) {
  uint i = begin;
  for (; i < end; ++i) {
    samplerStart(smp, i);
    precise vec3 est = vec3(0.0);
    if (method == HT_METHOD_UNIFORM) {
      vec3 wi = sampleUniformSphere(samplerNext2D(smp));
      est = reflected(sh, wi, envEval(wi)) / uniformSpherePdf();
      directions += 1u;
    } else if (method == HT_METHOD_COSINE) {
      vec3 local = sampleCosineHemisphere(samplerNext2D(smp));
      float pdf = cosineHemispherePdf(local.z);
      if (pdf > 0.0) {
        vec3 wi = toWorld(sh.frame, local);
        est = reflected(sh, wi, envEval(wi)) / pdf;
      }
      directions += 1u;
    } else if (method == HT_METHOD_ENV) {
      EnvSample s = sampleEnvironmentAt(smp);
      if (s.pdf > 0.0) est = reflected(sh, s.dir, envRadiance(s.pixel)) / s.pdf;
      directions += 1u;
    } else if (method == HT_METHOD_BRDF) {
      float pdf;
      vec3 wi = bsdfDirection(sh, smp, pdf);
      if (pdf > 0.0) est = reflected(sh, wi, envEval(wi)) / pdf;
      directions += 1u;
    } else if (method == HT_METHOD_MIS) {
      EnvSample s = sampleEnvironmentAt(smp);
      if (s.pdf > 0.0) {
        float pb = bsdfPdf(sh.material, sh.woLocal, toLocal(sh.frame, s.dir));
        est += reflected(sh, s.dir, envRadiance(s.pixel)) * (powerHeuristic(s.pdf, pb) / s.pdf);
      }
      float pb;
      vec3 wi = bsdfDirection(sh, smp, pb);
      if (pb > 0.0) {
        float pe = environmentPdf(wi);
        est += reflected(sh, wi, envEval(wi)) * (powerHeuristic(pb, pe) / pb);
      }
      directions += 2u;
    }
    precise accvec3 total = sum + accvec3(est);
    sum = total;
  }
  return i - begin;
}

bool isHtMethod(uint method) { return method >= HT_METHOD_HT && method <= HT_METHOD_HT_VIS_BIASED; }
bool isWisMethod(uint method) { return method == HT_METHOD_WIS || method == HT_METHOD_WIS_BIASED; }

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

void storeWalk(inout GpuPixelState st, HtWalk w) {
  st.htSeed = w.seed;
  st.htFace = w.face;
  st.htLevel = w.level;
  st.htNode = w.node;
  st.htR = w.r;
  st.htLeafH = w.leafH;
}
HtWalk loadWalk(GpuPixelState st) {
  return HtWalk(st.htSeed, st.htFace, st.htLevel, st.htNode, st.htR, st.htLeafH);
}

// The first dispatch of a tile: the draws estimateDirect makes before its
// samples. Leaves st.done = 1 when there is nothing to sample.
void beginPixel(inout GpuPixelState st, Shading sh, vec3 position, vec3 normal, vec3 wo, uint method) {
  uint rng = st.rng;
  st.samplerSeed = rngNextUint(rng);
  if (isHtMethod(method)) {
    HtWalk w;
    bool work = htBegin(sh, position, normal, wo, pc.spp, rng, w);
    st.done = work ? 0u : 1u;
    storeWalk(st, w);
    st.htS = hrealToBits(ht.s);
    st.htU = hrealToBits(ht.u);
  } else if (method == HT_METHOD_RIS) {
    st.done = scene.envHasLight == 0u ? 1u : 0u;
  } else if (method == HT_METHOD_TSIS || isWisMethod(method)) {
    bool work = method == HT_METHOD_TSIS ? tsisPrepare(sh, normal, wo) : wisPrepare(sh, normal, wo);
    st.done = work ? 0u : 1u;
  }
  st.rng = rng;
}

// One batch of the pixel's estimate: pc.batchLimit samples or HT steps.
// False when its loop stopped before it should have (the driver's limit).
bool continuePixel(inout GpuPixelState st, Shading sh, vec3 position, vec3 normal, vec3 wo, uint method,
                   bool prepared) {
  Sampler smp = samplerInit(pc.samplerKind, st.samplerSeed);
  uint directions = st.directions;
  accvec3 sum = sumFromBits(st.sum);
  bool complete = true;
  if (isHtMethod(method)) {
    if (!prepared) {
      htInit(position, normal, wo, sh.material);
      ht.s = hrealFromBits(st.htS);
      ht.u = hrealFromBits(st.htU);
    }
    for (uint l = 0u; l <= uint(HT_MAX_ORDER); ++l) gHtPathMin[l] = st.htPathMin[l];
    HtWalk w = loadWalk(st);
    gHtSum = sum;
    gHtSamples = directions;
    uint taken;
    bool finished = htSteps(sh, w, pc.batchLimit, smp, taken);
    complete = finished || taken == pc.batchLimit;
    sum = gHtSum;
    directions = gHtSamples;
    storeWalk(st, w);
    for (uint l = 0u; l <= uint(HT_MAX_ORDER); ++l) st.htPathMin[l] = gHtPathMin[l];
    st.done = finished ? 1u : 0u;
  } else {
    uint begin = st.next;
    uint end = min(pc.spp, begin + pc.batchLimit);
    uint done = end - begin;
    if (method == HT_METHOD_RIS) {
      done = risSamples(sh, begin, end, pc.risCandidates, smp, sum, directions);
    } else if (method == HT_METHOD_TSIS) {
      if (prepared || tsisPrepare(sh, normal, wo)) done = tsisSamples(sh, begin, end, smp, sum, directions);
    } else if (isWisMethod(method)) {
      if (prepared || wisPrepare(sh, normal, wo))
        done = wisSamples(sh, begin, end, smp, method == HT_METHOD_WIS_BIASED, sum, directions);
    } else {
      done = baselineSamples(sh, method, begin, end, smp, sum, directions);
    }
    complete = done == end - begin;
    st.next = end;
    st.done = end >= pc.spp ? 1u : 0u;
  }
  st.directions = directions;
  sumToBits(sum, st.sum);
  return complete;
}

// The estimate of a finished pixel: the mean of its samples (HT: the sum of
// its weighted samples).
vec3 finishPixel(GpuPixelState st, uint method) {
  accvec3 sum = sumFromBits(st.sum);
  if (isHtMethod(method)) return vec3(sum);
  precise accvec3 mean = sum / accvec3(max(pc.spp, 1u));
  return vec3(mean);
}

// Mesa's llvmpipe ends every loop of an invocation once its loops have run
// 65535 iterations in all (gallivm's loop limiter). A loop of a few
// iterations, run last, tells whether that happened: the host then makes
// the batches smaller.
bool loopsWereCut() {
  uint n = 0u;
  for (uint i = 0u; i < pc.canaryLoops; ++i) n += 1u + (i & pc.canaryZero);
  return n != pc.canaryLoops;
}

void main() {
  uvec2 local = gl_GlobalInvocationID.xy;
  if (local.x >= pc.tileWidth || local.y >= pc.tileHeight) return;
  uint x = pc.tileX + local.x;
  uint y = pc.tileY + local.y;
  uint slot = local.y * pc.tileWidth + local.x;
  GpuPixel result;
  result.radiance = vec3(0.0);
  result.shaded = 0u;
  result.directions = 0u;
  result.shadowRays = 0u;
  result.htNodes = 0u;
  bool done = true, cut = false;

  precise float px = float(x) + 0.5;
  precise float py = float(y) + 0.5;
  Ray ray = cameraRay(px, py);
  Hit hit;
  if (!intersectScene(ray, 0.0, kInfinity, hit)) {
    result.radiance = envEval(ray.dir);
  } else {
    uint method = kSpecializedMethod == HT_METHOD_ANY ? pc.method : kSpecializedMethod;
    vec3 wo = -ray.dir;
    Shading sh;
    sh.frame = makeFrame(hit.normal);
    sh.woLocal = toLocal(sh.frame, wo);
    sh.origin = offsetRayOrigin(hit.position, hit.normal);
    sh.material = materials[hit.material];
    gHtMaterial = hit.material;
    GpuPixelState st;
    bool prepared = pc.batch == 0u;
    if (prepared) {
      st.rng = rngInit(pc.seed, y * pc.width + x);  // pixelStream(x, y, width)
      st.next = 0u;
      st.directions = 0u;
      st.shadowRays = 0u;
      st.htNodes = 0u;
      st.done = 0u;
      st.samplerSeed = 0u;
      st.pad = 0u;
      sumToBits(accvec3(0.0), st.sum);
      for (uint l = 0u; l <= uint(HT_MAX_ORDER); ++l) st.htPathMin[l] = 0.0;
      beginPixel(st, sh, hit.position, hit.normal, wo, method);
    } else {
      st = pc.pixelState.s[slot];
    }
    gShadowRays = st.shadowRays;
    gHtNodes = st.htNodes;
    if (st.done == 0u) cut = !continuePixel(st, sh, hit.position, hit.normal, wo, method, prepared);
    st.shadowRays = gShadowRays;
    st.htNodes = gHtNodes;
    pc.pixelState.s[slot] = st;
    done = st.done != 0u;
    if (done) result.radiance = finishPixel(st, method);
    result.shaded = 1u;
    result.directions = st.directions;
    result.shadowRays = st.shadowRays;
    result.htNodes = st.htNodes;
  }
  cut = loopsWereCut() || cut;
  result.status = (done ? HT_PIXEL_DONE : 0u) | (cut ? HT_PIXEL_LOOPS_CUT : 0u);
  pixels[slot] = result;
}
