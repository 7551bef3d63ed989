// The frame of every method's compute shader: one invocation per pixel of
// the current tile, its estimate spread over batches (one dispatch each) so
// that no dispatch runs long. A shader's main() is
//   if (!pixelStart(job)) return;            // outside the tile, or done
//   if (job.shade) { ...begin on job.fresh, continue while !gPixel.done... }
//   pixelEnd(job, estimate);
// and the state between batches is GpuPixelState (shaders/common.h).
#ifndef HT_PIXEL_GLSL
#define HT_PIXEL_GLSL

#include "shading.glsl"

layout(local_size_x = HT_WORKGROUP_SIZE, local_size_y = HT_WORKGROUP_SIZE) in;

// The method, read where it is used (the driver folds the specialization
// constant there, and drops the other methods' code).
uint pixelMethod() { return kSpecializedMethod == HT_METHOD_ANY ? pc.method : kSpecializedMethod; }


// The pixel's state between batches (GpuPixelState), a global of its own:
// lavapipe copies a struct holding arrays at every call that takes it.
GpuPixelState gPixel;

struct PixelJob {
  uint slot;       // index in the tile's buffers
  bool shade;      // the camera ray hit the scene
  bool fresh;      // first batch: the state starts here
  bool cut;        // a loop stopped before it should have
  vec3 position, normal, wo;
  uint materialIndex;
  bool planar;  // on a plane
  Shading sh;
  vec3 background;  // radiance of a ray that misses the scene
};

// Sets up the invocation's pixel: its camera ray, shading point and state
// (fresh, seeded as pixelStream(x, y, width) on the CPU, or the previous
// batch's). False outside the tile.
bool pixelStart(out PixelJob job) {
  uvec2 local = gl_GlobalInvocationID.xy;
  if (local.x >= pc.tileWidth || local.y >= pc.tileHeight) return false;
  uint x = pc.tileX + local.x;
  uint y = pc.tileY + local.y;
  job.slot = local.y * pc.tileWidth + local.x;
  job.fresh = pc.batch == 0u;
  // A pixel done in an earlier batch keeps the result it wrote then.
  if (!job.fresh && pc.pixelState.s[job.slot].done != 0u) return false;
  job.cut = false;
  job.background = vec3(0.0);
  job.planar = false;

  precise float px = float(x) + 0.5;
  precise float py = float(y) + 0.5;
  Ray ray = cameraRay(px, py);
  Hit hit;
  job.shade = intersectScene(ray, 0.0, kInfinity, hit);
  if (!job.shade) {
    job.background = envEval(ray.dir);
    gPixel.done = 1u;
    sumToBits(accvec3(0.0), gPixel.sum);
    return true;
  }
  job.position = hit.position;
  job.normal = hit.normal;
  job.wo = -ray.dir;
  job.materialIndex = hit.material;
  job.planar = hit.planar;
  job.sh.frame = makeFrame(hit.normal);
  job.sh.woLocal = toLocal(job.sh.frame, job.wo);
  job.sh.origin = offsetRayOrigin(hit.position, hit.normal);
  job.sh.material = materials[hit.material];
  if (job.fresh) {
    gPixel.rng = rngInit(pc.seed, y * pc.width + x);
    gPixel.next = 0u;
    gPixel.directions = 0u;
    gPixel.shadowRays = 0u;
    gPixel.htNodes = 0u;
    gPixel.done = 0u;
    gPixel.samplerSeed = rngNextUint(gPixel.rng);  // estimateDirect's first draw
    gPixel.loopsCut = 0u;
    gPixel.htResume = 0u;
    gPixel.pad2 = 0u;
    gPixel.htResumeI = 0ul;
    sumToBits(accvec3(0.0), gPixel.sum);
    for (uint l = 0u; l <= uint(HT_MAX_ORDER); ++l) gPixel.htPathMin[l] = 0.0;
  } else {
    gPixel = pc.pixelState.s[job.slot];
  }
  gShadowRays = gPixel.shadowRays;
  return true;
}

Sampler pixelSampler() { return samplerInit(pc.samplerKind, gPixel.samplerSeed); }

// The mean of a finished pixel's spp samples.
vec3 pixelMean() {
  precise accvec3 mean = sumFromBits(gPixel.sum) / accvec3(max(pc.spp, 1u));
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

// Stores the state for the next batch and the pixel's result; `estimate`
// counts once the state is done. A loop cut short stays in the state, so
// that the last batch of a submission, the one the host reads, reports a
// cut in any batch before it.
void pixelEnd(PixelJob job, vec3 estimate) {
  GpuPixel result;
  result.radiance = job.background;
  result.shaded = 0u;
  result.directions = 0u;
  result.shadowRays = 0u;
  result.htNodes = 0u;
  bool done = true;
  bool cut = loopsWereCut() || job.cut;
  if (!job.shade) {
    pc.pixelState.s[job.slot].done = 1u;  // so that the later batches skip it
  } else {
    cut = cut || gPixel.loopsCut != 0u;
    gPixel.loopsCut = cut ? 1u : 0u;
    gPixel.shadowRays = gShadowRays;
    pc.pixelState.s[job.slot] = gPixel;
    done = gPixel.done != 0u;
    result.radiance = done ? estimate : vec3(0.0);
    result.shaded = 1u;
    result.directions = gPixel.directions;
    result.shadowRays = gPixel.shadowRays;
    result.htNodes = gPixel.htNodes;
  }
  result.status = (done ? HT_PIXEL_DONE : 0u) | (cut ? HT_PIXEL_LOOPS_CUT : 0u);
  pixels[job.slot] = result;
}

#endif
