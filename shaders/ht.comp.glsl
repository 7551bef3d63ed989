// The seed's hierarchical thresholding (ht.glsl): ht, ht-vis, ht-biased and
// ht-vis-biased, accepting the CPU's candidates for the same pixel and seed.
// A batch runs pc.batchLimit steps of the stackless traversal; the walks'
// positions, the recorded leaves and the path's minima carry over in
// GpuPixelState and the pixel's queue.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_control_flow_attributes : require

#include "pixel.glsl"
#include "ht.glsl"

void storeWalk(HtWalk w) {
  gPixel.htSeed = w.seed;
  gPixel.htFace = w.face;
  gPixel.htLevel = w.level;
  gPixel.htNode = w.node;
  gPixel.htR = w.r;
  gPixel.htLeafCount = w.leafCount;
  gPixel.htLeafNext = w.leafNext;
  gPixel.htCellActive = w.cellActive ? 1u : 0u;
  gPixel.htCellLevel = w.cellLevel;
  gPixel.htCellNode = w.cellNode;
  gPixel.htCellR = w.cellR;
  gPixel.htLeafH = w.leafH;
  gPixel.htResume = w.resume ? 1u : 0u;
  gPixel.htResumeI = hrealToBits(w.resumeI);
}
HtWalk loadWalk() {
  return HtWalk(gPixel.htSeed, gPixel.htFace, gPixel.htLevel, gPixel.htNode, gPixel.htR, gPixel.htLeafCount,
                gPixel.htLeafNext, gPixel.htCellActive != 0u, gPixel.htCellLevel, gPixel.htCellNode, gPixel.htCellR,
                gPixel.htLeafH, gPixel.htResume != 0u, hrealFromBits(gPixel.htResumeI));
}

void main() {
  PixelJob job;
  if (!pixelStart(job)) return;
  if (job.shade) {
    gHtMaterial = job.materialIndex;
    gHtNodes = gPixel.htNodes;
    HtWalk w;
    if (job.fresh) {
      bool work = htBegin(job.sh, job.position, job.normal, job.wo, pc.spp, gPixel.rng, w);
      gPixel.done = work ? 0u : 1u;
      storeWalk(w);
      gPixel.htS = hrealToBits(ht.s);
      gPixel.htU = hrealToBits(ht.u);
    } else {
      htInit(job.position, job.normal, job.wo, job.sh.material);
      ht.s = hrealFromBits(gPixel.htS);
      ht.u = hrealFromBits(gPixel.htU);
    }
    if (gPixel.done == 0u) {
      for (uint l = 0u; l <= uint(HT_MAX_ORDER); ++l) gHtPathMin[l] = gPixel.htPathMin[l];
      w = loadWalk();
      gHtSum = sumFromBits(gPixel.sum);
      gHtSamples = gPixel.directions;
      Sampler smp = pixelSampler();
      uint taken;
      bool finished = htSteps(job.sh, w, pc.batchLimit, smp, taken);
      job.cut = !finished && taken != pc.batchLimit;
      sumToBits(gHtSum, gPixel.sum);
      gPixel.directions = gHtSamples;
      storeWalk(w);
      for (uint l = 0u; l <= uint(HT_MAX_ORDER); ++l) gPixel.htPathMin[l] = gHtPathMin[l];
      gPixel.done = finished ? 1u : 0u;
    }
    gPixel.htNodes = gHtNodes;
  }
  // HT's estimate is the sum of its weighted samples.
  pixelEnd(job, vec3(sumFromBits(gPixel.sum)));
}
