// The talk's other product samplers (competitors.glsl): wis, wis-biased,
// tsis and ris, draw for draw as on the CPU.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require

#include "pixel.glsl"
#include "competitors.glsl"

bool isWisMethod(uint method) { return method == HT_METHOD_WIS || method == HT_METHOD_WIS_BIASED; }

// Whether there is anything to sample; tsis and wis build their per-point
// tables here, again in every batch.
bool prepare(PixelJob job) {
  if (pixelMethod() == HT_METHOD_TSIS) return tsisPrepare(job.sh, job.normal, job.wo);
  if (isWisMethod(pixelMethod())) return wisPrepare(job.sh, job.normal, job.wo);
  return scene.envHasLight != 0u;
}

void main() {
  PixelJob job;
  if (!pixelStart(job)) return;
  if (job.shade && gPixel.done == 0u && !prepare(job)) gPixel.done = 1u;
  if (job.shade && gPixel.done == 0u) {
    Sampler smp = pixelSampler();
    accvec3 sum = sumFromBits(gPixel.sum);
    uint begin = gPixel.next;
    uint end = min(pc.spp, begin + pc.batchLimit);
    uint taken;
    if (pixelMethod() == HT_METHOD_RIS)
      taken = risSamples(job.sh, begin, end, pc.risCandidates, smp, sum, gPixel.directions);
    else if (pixelMethod() == HT_METHOD_TSIS)
      taken = tsisSamples(job.sh, begin, end, smp, sum, gPixel.directions);
    else
      taken = wisSamples(job.sh, begin, end, smp, pixelMethod() == HT_METHOD_WIS_BIASED, sum, gPixel.directions);
    job.cut = taken != end - begin;
    sumToBits(sum, gPixel.sum);
    gPixel.next = end;
    gPixel.done = end >= pc.spp ? 1u : 0u;
  }
  pixelEnd(job, pixelMean());
}
