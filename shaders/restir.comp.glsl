// restir and restir-biased (host/restir.h): one pass of a group of reuse
// chains over the whole image per dispatch. Batch b is pass b mod (r + 2)
// of group b / (r + 2): 0 resamples each pixel's candidates, 1..r reuse
// the neighbours' reservoirs, r + 1 shades. Draw for draw as on the CPU.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require

#include "pixel.glsl"
#include "competitors.glsl"

Shading restirShading(GpuRestirPoint p) {
  Shading sh;
  sh.frame = makeFrame(p.normal);
  sh.woLocal = toLocal(sh.frame, p.wo);
  sh.origin = offsetRayOrigin(p.position, p.normal);
  sh.material = materials[p.material];
  return sh;
}

// p_hat at a point: luminance(L f cos), unshadowed (RisSampler::target).
float restirTarget(Shading sh, GpuRestirReservoir r) {
  precise vec3 product = r.radiance * evalBsdf(sh.material, sh.woLocal, toLocal(sh.frame, r.dir));
  return luminance(product);
}

bool restirSimilar(GpuRestirPoint a, GpuRestirPoint b) {
  if (b.material == HT_RESTIR_NO_HIT) return false;
  precise float nx = a.normal.x * b.normal.x;
  precise float ny = a.normal.y * b.normal.y;
  precise float nz = a.normal.z * b.normal.z;
  precise float cosine = (nx + ny) + nz;
  precise float gap = abs(b.depth - a.depth);
  precise float allowed = 0.1 * a.depth;
  return cosine >= 0.9063 && gap <= allowed;
}

GpuRestirPoint restirPointOf(PixelJob job) {
  GpuRestirPoint p;
  p.material = HT_RESTIR_NO_HIT;
  p.position = vec3(0.0);
  p.normal = vec3(0.0);
  p.depth = 0.0;
  p.wo = vec3(0.0);
  p.planar = 0u;
  if (!job.shade) return p;
  p.position = job.position;
  p.material = job.materialIndex;
  p.normal = job.normal;
  p.wo = job.wo;
  p.planar = job.planar ? 1u : 0u;
  precise vec3 d = job.position - scene.camPosition;
  precise float dx = d.x * scene.camW.x;
  precise float dy = d.y * scene.camW.y;
  precise float dz = d.z * scene.camW.z;
  precise float depth = (dx + dy) + dz;
  p.depth = depth;
  return p;
}

// restirInitial: the `ris` method's sample of chain `chain`; restir-biased
// zeroes W where it is blocked.
GpuRestirReservoir restirInitial(Shading sh, uint chain, inout Sampler smp, inout uint directions) {
  uint m = max(pc.risCandidates, 1u);
  accreal weight;
  RisCandidate chosen = risSample(sh, chain, m, smp, weight);
  directions += m;
  GpuRestirReservoir r;
  r.dir = chosen.dir;
  r.W = float(weight);
  r.radiance = chosen.radiance;
  r.M = m;
  if (pixelMethod() != HT_METHOD_RESTIR && r.W > 0.0) {
    ++gShadowRays;
    if (occluded(sh.origin, r.dir)) r.W = 0.0;
  }
  return r;
}

// restirRound at pixel (x, y) of one chain, from reservoir set `from`.
GpuRestirReservoir restirRound(Shading sh, GpuRestirPoint q, uint x, uint y, uint chainSlot, RestirReservoirs from,
                               uint roundSeed) {
  RestirPoints points = scene.restirPoints;
  uint pixelCount = pc.width * pc.height;
  uint self = y * pc.width + x;
  uint rng = rngInit(roundSeed, self);
  uint taken[1 + HT_RESTIR_MAX_NEIGHBOURS];
  uint count = 0u;
  taken[count++] = self;
  int radius = int(scene.restirRadius);
  uint side = 2u * scene.restirRadius + 1u;
  for (uint j = 0u; j < scene.restirNeighbours; ++j) {
    int dx = int(rngNextUint(rng) % side) - radius;
    int dy = int(rngNextUint(rng) % side) - radius;
    int nx = int(x) + dx;
    int ny = int(y) + dy;
    if ((dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= int(pc.width) || ny >= int(pc.height)) continue;
    uint n = uint(ny) * pc.width + uint(nx);
    if (restirSimilar(q, points.v[n])) taken[count++] = n;
  }
  precise accreal weightSum = 0.0;
  uint confidence = 0u;
  int chosen = -1;
  for (uint i = 0u; i < count; ++i) {
    GpuRestirReservoir r = from.v[chainSlot * pixelCount + taken[i]];
    confidence += r.M;
    float t = r.W > 0.0 ? restirTarget(sh, r) : 0.0;
    precise accreal w = 0.0;
    if (t > 0.0) {
      if (pixelMethod() == HT_METHOD_RESTIR) {
        // The balance heuristic over the reservoirs taken.
        precise accreal own = 0.0;
        precise accreal all = 0.0;
        for (uint j = 0u; j < count; ++j) {
          GpuRestirPoint p = points.v[taken[j]];
          precise accreal term = accreal(from.v[chainSlot * pixelCount + taken[j]].M) *
                                 accreal(restirTarget(restirShading(p), r));
          all += term;
          if (j == i) own = term;
        }
        w = own / all * accreal(t) * accreal(r.W);
      } else {
        w = accreal(t) * accreal(r.W) * accreal(r.M);
      }
    }
    float u = rngNext(rng);
    if (!(w > 0.0)) continue;
    weightSum += w;
    precise accreal scaled = accreal(u) * weightSum;
    if (scaled < w) chosen = int(i);
  }
  GpuRestirReservoir out_;
  out_.dir = from.v[chainSlot * pixelCount + self].dir;
  out_.radiance = from.v[chainSlot * pixelCount + self].radiance;
  out_.W = 0.0;
  out_.M = confidence;
  if (chosen < 0) return out_;
  out_.dir = from.v[chainSlot * pixelCount + taken[chosen]].dir;
  out_.radiance = from.v[chainSlot * pixelCount + taken[chosen]].radiance;
  precise accreal target = accreal(restirTarget(sh, out_));
  precise accreal W = pixelMethod() == HT_METHOD_RESTIR ? weightSum / target
                                                        : weightSum / (accreal(confidence) * target);
  out_.W = float(W);
  return out_;
}

// restirShade: L f cos V W.
accvec3 restirShade(Shading sh, GpuRestirReservoir r) {
  if (!(r.W > 0.0)) return accvec3(0.0);
  if (pixelMethod() == HT_METHOD_RESTIR || scene.restirRounds > 0u) {
    ++gShadowRays;
    if (occluded(sh.origin, r.dir)) return accvec3(0.0);
  }
  precise vec3 fcos = evalBsdf(sh.material, sh.woLocal, toLocal(sh.frame, r.dir));
  precise vec3 product = r.radiance * fcos;
  precise accvec3 c = accvec3(product) * accreal(r.W);
  return c;
}

void main() {
  PixelJob job;
  if (!pixelStart(job)) return;
  uint x = pc.tileX + gl_GlobalInvocationID.x, y = pc.tileY + gl_GlobalInvocationID.y;
  uint self = y * pc.width + x;
  uint pixelCount = pc.width * pc.height;
  GpuRestirPoint q = restirPointOf(job);
  if (pc.batch == 0u) scene.restirPoints.v[self] = q;
  if (job.shade && gPixel.done == 0u) {
    uint passes = scene.restirRounds + 2u;
    uint pass = pc.batch % passes;
    uint chains = max(min(pc.batchLimit, scene.restirChains), 1u);
    uint begin = (pc.batch / passes) * chains;
    uint end = min(pc.spp, begin + chains);
    accvec3 sum = sumFromBits(gPixel.sum);
    Sampler smp = pixelSampler();
    for (uint c = begin; c < end; ++c) {
      uint slot = (c - begin) * pixelCount + self;
      if (pass == 0u) {
        scene.restirReservoirs[0].v[slot] = restirInitial(job.sh, c, smp, gPixel.directions);
      } else if (pass <= scene.restirRounds) {
        uint seed = hashCombine(hashCombine(pc.seed, 0x52535452u + pass), c);
        scene.restirReservoirs[pass & 1u].v[slot] =
            restirRound(job.sh, q, x, y, c - begin, scene.restirReservoirs[(pass - 1u) & 1u], seed);
      } else {
        precise accvec3 total = sum + restirShade(job.sh, scene.restirReservoirs[scene.restirRounds & 1u].v[slot]);
        sum = total;
      }
    }
    sumToBits(sum, gPixel.sum);
    if (pass == passes - 1u) {
      gPixel.next = end;
      gPixel.done = end >= pc.spp ? 1u : 0u;
    }
  }
  pixelEnd(job, pixelMean());
}
