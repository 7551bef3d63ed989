// The baseline methods of host/methods/baselines.cpp (uniform, cosine, env, brdf,
// mis, mis-compensated), sample for sample as on the CPU.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require

#include "pixel.glsl"

// estimateDirect's samples [begin, end); returns how many it took.
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
    } else if (method == HT_METHOD_MIS || method == HT_METHOD_MIS_COMPENSATED) {
      // mis-compensated: the scene's sampling tree is its compensated one.
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

void main() {
  PixelJob job;
  if (!pixelStart(job)) return;
  if (job.shade && gPixel.done == 0u) {
    Sampler smp = pixelSampler();
    accvec3 sum = sumFromBits(gPixel.sum);
    uint end = min(pc.spp, gPixel.next + pc.batchLimit);
    uint taken = baselineSamples(job.sh, pixelMethod(), gPixel.next, end, smp, sum, gPixel.directions);
    job.cut = taken != end - gPixel.next;
    sumToBits(sum, gPixel.sum);
    gPixel.next = end;
    gPixel.done = end >= pc.spp ? 1u : 0u;
  }
  pixelEnd(job, pixelMean());
}
