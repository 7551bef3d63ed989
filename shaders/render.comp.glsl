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

// The CPU draws u as glm::vec3 u(rng.next(), rng.next(), rng.next()), whose
// arguments g++ evaluates right to left: u.z is the first draw, u.x the last.
vec3 drawBsdfU(inout uint rng) {
  float first = rngNext(rng);
  float second = rngNext(rng);
  float third = rngNext(rng);
  return vec3(third, second, first);
}

precise vec3 bsdfDirection(Shading sh, inout uint rng, out float pdf) {
  vec3 u = drawBsdfU(rng);
  precise vec3 local = sampleBsdf(sh.material, sh.woLocal, u);
  pdf = bsdfPdf(sh.material, sh.woLocal, local);
  return toWorld(sh.frame, local);
}

#if HT_FP64
#define accvec3 dvec3
#else
#define accvec3 vec3
#endif

#include "competitors.glsl"
#include "ht.glsl"

// estimateDirect for the baseline methods; counts directions drawn.
vec3 estimateDirect(vec3 position, vec3 normal, vec3 wo, GpuMaterial material, uint method, uint spp,
                    inout uint rng, inout uint directions) {
  Shading sh;
  sh.frame = makeFrame(normal);
  sh.woLocal = toLocal(sh.frame, wo);
  sh.origin = offsetRayOrigin(position, normal);
  sh.material = material;
  if (method == HT_METHOD_RIS) return estimateRis(sh, spp, pc.risCandidates, rng, directions);
  if (method == HT_METHOD_TSIS) return estimateTsis(sh, normal, wo, spp, rng, directions);
  if (method == HT_METHOD_WIS || method == HT_METHOD_WIS_BIASED)
    return estimateWis(sh, normal, wo, spp, method == HT_METHOD_WIS_BIASED, rng, directions);
  if (method >= HT_METHOD_HT && method <= HT_METHOD_HT_VIS_BIASED)
    return estimateHt(sh, position, normal, wo, spp, rng, directions);
  precise accvec3 sum = accvec3(0.0);
  for (uint i = 0u; i < spp; ++i) {
    precise vec3 est = vec3(0.0);
    if (method == HT_METHOD_UNIFORM) {
      float u0 = rngNext(rng);
      float u1 = rngNext(rng);
      vec3 wi = sampleUniformSphere(vec2(u0, u1));
      est = reflected(sh, wi, envEval(wi)) / uniformSpherePdf();
      directions += 1u;
    } else if (method == HT_METHOD_COSINE) {
      float u0 = rngNext(rng);
      float u1 = rngNext(rng);
      vec3 local = sampleCosineHemisphere(vec2(u0, u1));
      float pdf = cosineHemispherePdf(local.z);
      if (pdf > 0.0) {
        vec3 wi = toWorld(sh.frame, local);
        est = reflected(sh, wi, envEval(wi)) / pdf;
      }
      directions += 1u;
    } else if (method == HT_METHOD_ENV) {
      EnvSample s = sampleEnvironment(rng);
      if (s.pdf > 0.0) est = reflected(sh, s.dir, envRadiance(s.pixel)) / s.pdf;
      directions += 1u;
    } else if (method == HT_METHOD_BRDF) {
      float pdf;
      vec3 wi = bsdfDirection(sh, rng, pdf);
      if (pdf > 0.0) est = reflected(sh, wi, envEval(wi)) / pdf;
      directions += 1u;
    } else if (method == HT_METHOD_MIS) {
      EnvSample s = sampleEnvironment(rng);
      if (s.pdf > 0.0) {
        float pb = bsdfPdf(sh.material, sh.woLocal, toLocal(sh.frame, s.dir));
        est += reflected(sh, s.dir, envRadiance(s.pixel)) * (powerHeuristic(s.pdf, pb) / s.pdf);
      }
      float pb;
      vec3 wi = bsdfDirection(sh, rng, pb);
      if (pb > 0.0) {
        float pe = environmentPdf(wi);
        est += reflected(sh, wi, envEval(wi)) * (powerHeuristic(pb, pe) / pb);
      }
      directions += 2u;
    }
    sum += accvec3(est);
  }
  precise accvec3 mean = sum / accvec3(max(spp, 1u));
  return vec3(mean);
}

void main() {
  uvec2 local = gl_GlobalInvocationID.xy;
  if (local.x >= pc.tileWidth || local.y >= pc.tileHeight) return;
  uint x = pc.tileX + local.x;
  uint y = pc.tileY + local.y;
  GpuPixel result;
  result.shaded = 0u;
  result.directions = 0u;
  result.shadowRays = 0u;
  result.htNodes = 0u;
  result.reserved = 0u;

  precise float px = float(x) + 0.5;
  precise float py = float(y) + 0.5;
  Ray ray = cameraRay(px, py);
  Hit hit;
  if (!intersectScene(ray, 0.0, kInfinity, hit)) {
    result.radiance = envEval(ray.dir);
  } else {
    uint rng = rngInit(pc.seed, y * pc.width + x);  // pixelStream(x, y, width)
    uint directions = 0u;
    gHtMaterial = hit.material;
    result.radiance = estimateDirect(hit.position, hit.normal, -ray.dir, materials[hit.material],
                                     kSpecializedMethod == HT_METHOD_ANY ? pc.method : kSpecializedMethod,
                                     pc.spp, rng, directions);
    result.shaded = 1u;
    result.directions = directions;
    result.shadowRays = gShadowRays;
    result.htNodes = gHtNodes;
  }
  pixels[local.y * pc.tileWidth + local.x] = result;
}
