// The seed's hierarchical thresholding (ht.glsl): ht, ht-vis, ht-biased and
// ht-vis-biased, accepting the CPU's candidates for the same pixel and seed.
// A batch runs pc.batchLimit steps of the stackless traversal; the walk's
// position and the path's minima carry over in GpuPixelState.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require

#include "pixel.glsl"
#include "ht.glsl"

void storeWalk(inout GpuPixelState st, HtWalk w) {
  st.htSeed = w.seed;
  st.htFace = w.face;
  st.htLevel = w.level;
  st.htNode = w.node;
  st.htR = w.r;
  st.htLeafH = w.leafH;
  st.htResume = w.resume ? 1u : 0u;
  st.htResumeI = hrealToBits(w.resumeI);
}
HtWalk loadWalk(GpuPixelState st) {
  return HtWalk(st.htSeed, st.htFace, st.htLevel, st.htNode, st.htR, st.htLeafH, st.htResume != 0u,
                hrealFromBits(st.htResumeI));
}

void main() {
  PixelJob job;
  if (!pixelStart(job)) return;
  if (job.shade) {
    gHtMaterial = job.materialIndex;
    gHtNodes = job.st.htNodes;
    HtWalk w;
    if (job.fresh) {
      bool work = htBegin(job.sh, job.position, job.normal, job.wo, pc.spp, job.st.rng, w);
      job.st.done = work ? 0u : 1u;
      storeWalk(job.st, w);
      job.st.htS = hrealToBits(ht.s);
      job.st.htU = hrealToBits(ht.u);
    } else {
      htInit(job.position, job.normal, job.wo, job.sh.material);
      ht.s = hrealFromBits(job.st.htS);
      ht.u = hrealFromBits(job.st.htU);
    }
    if (job.st.done == 0u) {
      for (uint l = 0u; l <= uint(HT_MAX_ORDER); ++l) gHtPathMin[l] = job.st.htPathMin[l];
      w = loadWalk(job.st);
      gHtSum = sumFromBits(job.st.sum);
      gHtSamples = job.st.directions;
      Sampler smp = pixelSampler(job.st);
      uint taken;
      bool finished = htSteps(job.sh, w, pc.batchLimit, smp, taken);
      job.cut = !finished && taken != pc.batchLimit;
      sumToBits(gHtSum, job.st.sum);
      job.st.directions = gHtSamples;
      storeWalk(job.st, w);
      for (uint l = 0u; l <= uint(HT_MAX_ORDER); ++l) job.st.htPathMin[l] = gHtPathMin[l];
      job.st.done = finished ? 1u : 0u;
    }
    job.st.htNodes = gHtNodes;
  }
  // HT's estimate is the sum of its weighted samples.
  pixelEnd(job, vec3(sumFromBits(job.st.sum)));
}
