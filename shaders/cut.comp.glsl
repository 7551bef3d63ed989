// ht-cut (cut.glsl): every batch weighs the cut again at the pixel's point
// and draws the next of its n directions, as many as pc.batchLimit.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_control_flow_attributes : require
#extension GL_KHR_shader_subgroup_vote : require

// The caps a point keeps (caps.glsl's selection).
#define HT_CAP_LIST HT_CUT_MAX_CAPS
#include "pixel.glsl"
#include "cut.glsl"

void main() {
  PixelJob job;
  if (!pixelStart(job)) return;
  if (job.shade && gPixel.done == 0u) {
    Sampler smp = pixelSampler();
    accvec3 sum = sumFromBits(gPixel.sum);
    uint begin = gPixel.next;
    uint end = min(pc.spp, begin + pc.batchLimit);
    bool empty;
    uint taken = cutSamples(job.sh, job.position, job.normal, pc.spp, begin, end, gPixel.rng, smp, sum,
                            gPixel.directions, empty);
    job.cut = taken != end - begin;
    sumToBits(sum, gPixel.sum);
    gPixel.next = end;
    gPixel.done = empty || end >= pc.spp ? 1u : 0u;
  }
  // The estimate is the sum of the n weighted directions; a channel the
  // control variate on colour takes below 0 is set to 0.
  pixelEnd(job, vec3(max(sumFromBits(gPixel.sum), accvec3(0.0))));
}
