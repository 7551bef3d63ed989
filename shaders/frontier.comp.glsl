// ht-frontier (frontier.glsl): a pixel's first batch builds its table, and
// every batch, the first too, draws the next of its n directions, as many
// as pc.batchLimit. The directions resume from the stored point also in the
// first batch, which makes the same image whatever the batches.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_control_flow_attributes : require

#include "pixel.glsl"
#include "frontier.glsl"

void main() {
  PixelJob job;
  if (!pixelStart(job)) return;
  if (job.shade && gPixel.done == 0u) {
    gHtMaterial = job.materialIndex;
    if (job.fresh) {
      uint nodes = gPixel.htNodes;
      bool work = frontierBegin(job.position, job.normal, job.wo, job.sh.material, job.planar, job.slot, pc.spp,
                                gPixel.rng, nodes);
      gPixel.htNodes = nodes;
      gPixel.done = work ? 0u : 1u;
    }
    if (gPixel.done == 0u) {
      GpuFrontierPoint pt = frontierResume(job.position, job.normal, job.wo, job.sh.material, job.slot);
      Sampler smp = pixelSampler();
      accvec3 sum = sumFromBits(gPixel.sum);
      uint begin = gPixel.next;
      uint end = min(pc.spp, begin + pc.batchLimit);
      uint taken = frontierSamples(job.sh, pt, begin, end, smp, sum, gPixel.directions);
      job.cut = taken != end - begin;
      sumToBits(sum, gPixel.sum);
      gPixel.next = end;
      gPixel.done = end >= pc.spp ? 1u : 0u;
    }
  }
  // The estimate is the sum of the n weighted directions; a channel the
  // control variate on colour takes below 0 is set to 0.
  pixelEnd(job, vec3(max(sumFromBits(gPixel.sum), accvec3(0.0))));
}
