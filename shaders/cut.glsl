// ht-cut (host/ht_cut.cpp): a shading point weighs the cut's K nodes in one
// loop, the same for every pixel, and draws its directions from their
// prefix sums, below a node by its children's weights, and from the BRDF;
// draw for draw as on the CPU.
#ifndef HT_CUT_GLSL
#define HT_CUT_GLSL

#include "caps.glsl"
#include "ht_point.glsl"

vec4 cutTreeTexel(uint i) {
  if (kTexels) return texelFetch(cutTreeTexels, int(i));
  return scene.cutTree.v[i];
}
uint cutLookup(uint i) {
  if (kTexels) return texelFetch(cutLookupTexels, int(i)).x;
  return scene.cutLookup.v[i];
}
vec4 cutRecordTexel(uint i) {
  if (kTexels) return texelFetch(cutRecordTexels, int(i));
  return scene.cutRecord.v[i];
}

// What CutPoint::weight reads of a node (GpuScene::cutRecord's layout).
struct CutNodeData {
  vec3 centre;
  float sinR;  // of its disc
  vec3 moment;
  float power;
  vec3 chroma;  // a cut node's; 0 for its children
  float cosRb, sinRb;  // its level's bounding radius
  float chord;         // its disc's radius
  uint level, at;
};
CutNodeData cutRecord(uint r) {
  vec4 a = cutRecordTexel(4u * r), b = cutRecordTexel(4u * r + 1u), c = cutRecordTexel(4u * r + 2u),
       d = cutRecordTexel(4u * r + 3u);
  return CutNodeData(a.xyz, a.w, b.xyz, b.w, c.xyz, c.w, d.x, d.y, uint(d.z), uint(d.w));
}
// The same from the tree's records, for the nodes below the cut's.
CutNodeData cutTreeNode(uint level, uint at) {
  vec4 a = cutTreeTexel(3u * at), b = cutTreeTexel(3u * at + 1u);
  return CutNodeData(a.xyz, scene.cutDiscSin[level], b.xyz, a.w, vec3(0.0), scene.cutLevelCos[level],
                     scene.cutLevelSin[level], scene.cutDiscChord[level], level, at);
}

// The point (CutPoint), in the HEALPix frame.
struct CutPoint {
  vec3 s, t, normal;
  vec3 woLocal;
  float diffuse;
  bool apart, lobeOnly;
  GpuMaterial lobe;
};
CutPoint gCut;
// Its caps, from occluderSlots' first HT_CUT_MAX_CAPS slots: axis, cos and
// sin of the half-angle less the margin, the radius's chord; gCutCaps: the
// slots set.
vec3 gCutCapAxis[HT_CUT_MAX_CAPS];
float gCutCapSin[HT_CUT_MAX_CAPS];
float gCutCapCos[HT_CUT_MAX_CAPS];
float gCutCapChord[HT_CUT_MAX_CAPS];
uint gCutCaps;
// The slots the caps' loops visit: the scene's, at most the cut's.
const uint kCutCapSlots = kCapSlots < uint(HT_CUT_MAX_CAPS) ? kCapSlots : uint(HT_CUT_MAX_CAPS);
// The cut's prefix sums at the point (cum[k]: the weights before node k).
float gCutCum[HT_CUT_MAX_NODES + 1];
// The cut nodes whose children the point weighs, a bit per node: a list
// of their indices took 2 KB of each invocation's private memory, which
// cost lavapipe about a tenth of its time.
uint gCutRefined[HT_CUT_MAX_NODES / 32];

void cutAddCap(uint k, vec3 axis, float s0) {
  // The plane the point lies on: its cap is the point's horizon, which the
  // weights already hold.
  if (dot3(axis, gCut.normal) < -0.9999) return;
  precise float c0 = sqrt(1.0 - s0 * s0);
  precise float sinA = s0 * scene.cutCapCosMargin - c0 * scene.cutCapSinMargin;
  precise float cosA = c0 * scene.cutCapCosMargin + s0 * scene.cutCapSinMargin;
  if (!(sinA > 0.0)) return;
  precise float chord = sqrt(max(2.0 - 2.0 * cosA, 0.0));
  gCutCapAxis[k] = axis;
  gCutCapSin[k] = sinA;
  gCutCapCos[k] = cosA;
  gCutCapChord[k] = chord;
  gCutCaps |= 1u << k;
}

// CutPoint's constructor: the frame, the lobes and the caps.
void cutInit(Shading sh, vec3 position, vec3 normal) {
  precise vec3 s = vec3(toHealpixFrame(sh.frame.s));
  precise vec3 t = vec3(toHealpixFrame(sh.frame.t));
  precise vec3 n = vec3(toHealpixFrame(sh.frame.n));
  gCut.s = s;
  gCut.t = t;
  gCut.normal = n;
  gCut.woLocal = sh.woLocal;
  GpuMaterial m = sh.material;
  bool hasLobe = m.type != HT_MATERIAL_LAMBERT && luminance(m.specular) > 0.0;
  gCut.apart = hasLobe && luminance(m.diffuse) > 0.0;
  gCut.lobeOnly = hasLobe && !gCut.apart;
  precise float diffuse = luminance(m.diffuse) * kInvPi;
  gCut.diffuse = diffuse;
  gCut.lobe = m;
  gCut.lobe.diffuse = vec3(0.0);
  gCut.lobe.specularProbability = luminance(m.specular) > 0.0 ? 1.0 : 0.0;  // specularLobeProbability
  gCutCaps = 0u;
  if ((scene.cutFlags & HT_CUT_VISIBILITY) == 0u) return;
  // The first HT_CUT_MAX_CAPS slots, each in its own (indices the loops
  // unroll to constants, so that the caps stay in registers).
  const uint slots = occluderSlots(position, normal, uint(HT_CUT_MAX_CAPS));
  [[unroll]] for (uint k = 0u; k < kCutCapSlots; ++k)
    if (((slots >> k) & 1u) != 0u) cutAddCap(k, gOccluderAxis[k], gOccluderSine[k]);
}

// cutClippedCosine.
precise float cutClippedCosine(float sinE, float sinR) {
  precise float a = sinE / sinR;
  precise float b = 1.0 + a;
  precise float c = 0.6953125 + 0.15234375 * b;
  precise float q = 0.25 * b * b;
  return sinR * (q * c);
}

// cutSegmentShare.
precise float cutSegmentShare(float x) {
  precise float a = min(x, 1.0 - x);
  precise float f = (a * sqrt(a)) * (1.697265625 - 0.56640625 * a);
  return x <= 0.5 ? f : 1.0 - f;
}

// CutPoint::weight of a node; `uncertain` set where the horizon or a cap
// cuts it.
precise float cutWeightOf(CutNodeData n, bool withLobe, inout bool uncertain) {
  precise float power = n.power;
  if (!(power > 0.0)) return 0.0;
  vec3 m = n.moment;
  vec3 centre = n.centre;
  precise float sinE = dot3(centre, gCut.normal);
  float sinR = n.sinR;
  precise float w = 0.0;
  // The lobe's code behind subgroupAny: a SIMD group without a lobe alone
  // skips it.
  if (subgroupAny(withLobe) && withLobe) {
    precise float len = sqrt(dot3(m, m));
    if (len > 0.0) {
      precise vec3 c = m / len;
      vec3 local = vec3(dot3(c, gCut.s), dot3(c, gCut.t), dot3(c, gCut.normal));
      precise float lobe = power * luminance(evalBsdf(gCut.lobe, gCut.woLocal, local));
      w = lobe;
    }
  } else if (gCut.diffuse > 0.0) {
    precise float d = dot3(m, gCut.normal);
    if (sinE < sinR) {
      d = sinE <= -sinR ? 0.0 : max(d, power * cutClippedCosine(sinE, sinR));
      if (sinE > -sinR) uncertain = true;
    }
    float cosR = n.cosRb, sinRb = n.sinRb;
    precise float cosE = sqrt(max(0.0, 1.0 - sinE * sinE));
    precise float top = sinE >= cosR ? 1.0 : sinE * cosR + cosE * sinRb;
    precise float floorW = float(HT_CUT_HORIZON_FLOOR) * power * max(top, 0.0);
    d = max(d, floorW);
    w = gCut.diffuse * d;
  }
  if (!(w > 0.0) || gCutCaps == 0u) return w;
  // The caps' cheap tests, and the cap reaching deepest into the node
  // (visibleShare); its covered share only where a lane of the SIMD group
  // has one (subgroupAny: a branch the whole group takes or skips, where
  // llvmpipe would otherwise run its code for every node).
  float rn = n.chord;
  float cR = n.cosRb, sR = n.sinRb;
  bool inside = false;
  float depth = 0.0, span = 1.0, deepest = 0.0, chord = 0.0;
  [[unroll]] for (uint k = 0u; k < kCutCapSlots; ++k) {
    if (((gCutCaps >> k) & 1u) == 0u) continue;
    precise float d = dot3(centre, gCutCapAxis[k]);
    precise float innerTest = gCutCapSin[k] * cR - gCutCapCos[k] * sR;
    precise float insideCos = innerTest > 0.0 ? gCutCapCos[k] * cR + gCutCapSin[k] * sR : 2.0;
    precise float outsideCos = gCutCapCos[k] * cR - gCutCapSin[k] * sR;
    inside = inside || d >= insideCos;
    precise float past = d - outsideCos;
    if (!(past > 0.0)) continue;
    precise float range = min(insideCos, 1.0) - outsideCos;
    precise float ahead = past * span;
    precise float behind = depth * range;
    if (ahead > behind) {
      depth = past;
      span = range;
      deepest = d;
      chord = gCutCapChord[k];
    }
  }
  if (inside) return 0.0;
  precise float visible = 1.0;
  if (subgroupAny(depth > 0.0) && depth > 0.0) {
    float small = min(rn, chord);
    precise float dist = sqrt(max(2.0 - 2.0 * deepest, 0.0));
    precise float x = clamp((dist - abs(rn - chord)) / (2.0 * small), 0.0, 1.0);
    precise float ratio = small / rn;
    precise float covered = (1.0 - cutSegmentShare(x)) * (ratio * ratio);
    visible = 1.0 - covered;
  }
  if (visible < 1.0) uncertain = true;
  precise float weighted = w * max(visible, scene.cutMinPartial);
  return weighted;
}

precise float cutWeight(uint level, uint at, inout bool uncertain) {
  return cutWeightOf(cutTreeNode(level, at), gCut.lobeOnly, uncertain);
}

// The children of `parent` (of level - 1) by their weights, by the average
// tree where none has any.
void cutChildWeights(uint level, uint parent, out float cw[4]) {
  uint first = levelOffset(level) + 4u * parent;
  bool unused = false;
  // A loop of four passes, not four copies: llvmpipe runs every copy's code
  // for the whole SIMD group.
  [[dont_unroll]] for (uint j = 0u; j < 4u; ++j) cw[j] = cutWeight(level, first + j, unused);
  precise float sum = ((cw[0] + cw[1]) + cw[2]) + cw[3];
  if (!(sum > 0.0))
    [[unroll]] for (uint j = 0u; j < 4u; ++j) cw[j] = treeAvg(first + j);
}

// pickRescaled<4> over four weights.
uint cutPick(float w[4], inout hreal u, out float prob) {
  precise float sum = 0.0;
  [[unroll]] for (uint i = 0u; i < 4u; ++i) sum += w[i];
  precise hreal target = u * hreal(sum);
  uint last = 0u;
  precise hreal before = 0.0;
  precise hreal acc = 0.0;
  bool found = false;
  [[unroll]] for (uint i = 0u; i < 4u; ++i) {
    if (found || w[i] <= 0.0) continue;
    last = i;
    before = acc;
    acc += hreal(w[i]);
    found = target < acc;
  }
  float wl = w[0];
  [[unroll]] for (uint i = 1u; i < 4u; ++i) wl = i == last ? w[i] : wl;
  precise float p = wl / sum;
  prob = p;
  precise hreal v = (target - before) / hreal(wl);
  u = clamp(v, hreal(0.0), kEnvBelowOne);
  return last;
}

// The point's weights over the cut into gCutCum (withLobe: a lobe alone's);
// returns their total and the weighted sum of the nodes' chroma.
float cutWeightsWith(bool withLobe, out vec3 chromaSum) {
  uint K = scene.cutCount;
  // The nodes' weights (node k's in gCutCum[k + 1]), and the bits of those
  // the horizon or a cap cuts.
  [[unroll]] for (uint w = 0u; w < uint(HT_CUT_MAX_NODES / 32); ++w) gCutRefined[w] = 0u;
  uint refined = 0u;
  for (uint k = 0u; k < K; ++k) {
    bool uncertain = false;
    CutNodeData n = cutRecord(k);
    gCutCum[k + 1u] = cutWeightOf(n, withLobe, uncertain);
    if (uncertain && n.level < scene.cutMomentLevel) {
      gCutRefined[k >> 5] |= 1u << (k & 31u);
      ++refined;
    }
  }
  // Their children, each lane its own nodes: llvmpipe runs a loop's body
  // for its SIMD group while any lane is in it, so the group pays the
  // longest list, not every node some lane refines.
  uint word = 0u;
  uint bits = gCutRefined[0];
  for (uint i = 0u; subgroupAny(i < refined); ++i) {
    if (i >= refined) continue;
    while (bits == 0u) bits = gCutRefined[++word];
    uint k = 32u * word + uint(findLSB(bits));
    bits &= bits - 1u;
    precise float children = 0.0;
    [[dont_unroll]] for (uint j = 0u; j < 4u; ++j) {
      bool unused = false;
      precise float v = cutWeightOf(cutRecord(K + 4u * k + j), withLobe, unused);
      children = children + v;
    }
    if (children > 0.0) gCutCum[k + 1u] = children;
  }
  // The prefix sums in place, in the CPU's order.
  precise float total = 0.0;
  precise vec3 chroma = vec3(0.0);
  for (uint k = 0u; k < K; ++k) {
    float w = gCutCum[k + 1u];
    gCutCum[k] = total;
    total = total + w;
    precise float share = total - gCutCum[k];
    chroma = chroma + share * cutRecordTexel(4u * k + 2u).xyz;
  }
  gCutCum[K] = total;
  chromaSum = chroma;
  return total;
}

// Two loops, of which a SIMD group without a lobe alone runs the cheaper.
float cutWeights(out vec3 chromaSum) {
  if (gCut.lobeOnly) return cutWeightsWith(true, chromaSum);
  return cutWeightsWith(false, chromaSum);
}

// The cut node k whose prefix sums hold `target` (upper_bound over 1..K-1),
// past nodes of no weight at the end.
uint cutFind(float target) {
  uint K = scene.cutCount;
  uint lo = 1u, hi = K;
  while (lo < hi) {
    uint mid = (lo + hi) >> 1;
    if (gCutCum[mid] > target) hi = mid;
    else lo = mid + 1u;
  }
  uint k = lo - 1u;
  while (k > 0u && !(gCutCum[k + 1u] - gCutCum[k] > 0.0)) --k;
  return k;
}

// The techniques of estimateHtCut: the counts, their weights in the
// balance heuristic, the systematic points' offset and the BRDF's material.
struct CutPlan {
  uint cutCount, brdfCount;
  float cWeight, bWeight;
  hreal offset;
  GpuMaterial bm;
};

CutPlan cutPlan(Shading sh, float total, uint n, uint rngState) {
  CutPlan plan;
  GpuMaterial mat = sh.material;
  plan.bm = gCut.apart ? gCut.lobe : mat;
  precise float share = 0.0;
  if (gCut.apart) {
    uint lobeLevel = min(uint(HT_FRONTIER_LOBE_LEVEL), scene.envOrder);
    precise vec3 mirror = toWorld(sh.frame, vec3(-sh.woLocal.x, -sh.woLocal.y, sh.woLocal.z));
    float mirrorRadiance = treeAvg(levelOffset(lobeLevel) + vecToPix(lobeLevel, toHealpixFrame(mirror)));
    precise float f0 = luminance(mat.specular);
    precise float q = 1.0 - clamp(sh.woLocal.z, 0.0, 1.0);
    precise float reflectance = mat.type == HT_MATERIAL_GGX ? f0 + (1.0 - f0) * (q * q * q * q * q) : f0;
    precise float lobeLight = reflectance * mirrorRadiance;
    precise float ratio = lobeLight / (lobeLight + total);
    share = clamp(ratio, float(HT_CUT_MIN_SHARE), 1.0 - float(HT_CUT_MIN_SHARE));
  } else if (gCut.lobeOnly) {
    // cutLobeShare.
    GpuMaterial m = sh.material;
    precise float width = m.type == HT_MATERIAL_PHONG ? 0.5 / sqrt(m.exponent + 1.0) : m.alpha;
    precise float rho = scene.cutLobeSpan;
    precise float ratio = rho / (rho + width);
    share = clamp(ratio, 0.25, 0.75);
  }
  bool mixture = n == 1u && share > 0.0;
  uint nb = 0u;
  if (share > 0.0 && n > 1u) {
    precise hreal scaled = hreal(share) * hreal(n) + hreal(0.5);
    nb = clamp(uint(floor(scaled)), 1u, n - 1u);
  }
  plan.cWeight = mixture ? 1.0 - share : float(n - nb);
  plan.bWeight = mixture ? share : float(nb);
  uint r = rngState;
  precise hreal offset = hreal(rngNext(r));
  plan.cutCount = n - nb;
  plan.brdfCount = nb;
  if (mixture) {
    bool fromCut = offset >= hreal(share);
    plan.cutCount = fromCut ? 1u : 0u;
    plan.brdfCount = 1u - plan.cutCount;
    precise hreal rest = fromCut ? (offset - hreal(share)) / (hreal(1.0) - hreal(share)) : offset / hreal(share);
    offset = rest;
  }
  plan.offset = offset;
  return plan;
}

// Directions [begin, end) of the point's n: the cut's first, then the
// BRDF's; false where the point has nothing to sample.
uint cutSamples(Shading sh, vec3 position, vec3 normal, uint n, uint begin, uint end, uint rngState,
                inout Sampler smp, inout accvec3 sum, inout uint directions, out bool empty) {
  cutInit(sh, position, normal);
  vec3 chromaSum;
  float total = cutWeights(chromaSum);
  empty = !(total > 0.0);
  if (empty) return end - begin;
  CutPlan plan = cutPlan(sh, total, n, rngState);
  GpuMaterial mat = sh.material;
  if (begin == 0u) directions += n;

  uint productLevel = min(scene.cutProductLevel, scene.cutMomentLevel);
  // A lobe alone has none: its weights are not its density's product.
  bool colourControl = (scene.cutFlags & HT_CUT_COLOUR_CONTROL) != 0u && plan.cutCount > 0u && !gCut.lobeOnly;
  vec3 fColour = colourControl ? mat.diffuse / luminance(mat.diffuse) : vec3(0.0);
  precise hreal scale = hreal(total) / hreal(plan.cWeight);
  precise accvec3 colourScale = accvec3(fColour) * scale;
  precise vec3 colourMean = chromaSum / total;

  uint j = begin;
  for (; j < min(end, plan.cutCount); ++j) {
    precise hreal x = (hreal(j) + plan.offset) / hreal(plan.cutCount);
    precise float target = float(x) * total;
    uint k = cutFind(target);
    CutNodeData cn = cutRecord(k);
    samplerStart(smp, j);
#if HT_FP64
    dvec2 u = samplerNext2DPrecise(smp);
#else
    vec2 u = samplerNext2DPrecise(smp);
#endif
    precise float share = (gCutCum[k + 1u] - gCutCum[k]) / total;
    precise hreal p = hreal(share);
    uint level = cn.level;
    uint node = cn.at - levelOffset(level);
    uint below = max(level, productLevel);
    hreal ux = u.x;
    // CutDensity::sample's colour drift: each step's expected chroma less
    // the drawn child's, then the last node's less the pixel's.
    precise accvec3 drift = accvec3(0.0);
    vec3 chroma = cn.chroma;
    for (uint l = level + 1u; l <= below; ++l) {
      float cw[4];
      cutChildWeights(l, node, cw);
      uint first = levelOffset(l) + 4u * node;
      precise accvec3 expected = accvec3(0.0);
      vec3 cc[4];
      if (colourControl) {
        precise hreal cwSum = ((hreal(cw[0]) + hreal(cw[1])) + hreal(cw[2])) + hreal(cw[3]);
        [[unroll]] for (uint i = 0u; i < 4u; ++i) {
          cc[i] = cutTreeTexel(3u * (first + i) + 2u).xyz;
          precise hreal share = hreal(cw[i]) / cwSum;
          expected = expected + share * accvec3(cc[i]);
        }
      }
      float prob;
      uint pick = cutPick(cw, ux, prob);
      node = 4u * node + pick;
      if (colourControl) {
        chroma = cc[0];
        [[unroll]] for (uint i = 1u; i < 4u; ++i) chroma = i == pick ? cc[i] : chroma;
        drift = drift + (expected - accvec3(chroma));
      }
      p *= hreal(prob);
    }
    EnvSample es = sampleEnvironmentBelow(below, node, ux, u.y);
    precise hreal pcH = p * hreal(es.pdf);
    if (colourControl && es.pdf > 0.0) {
      vec3 radiance = envRadiance(es.pixel);
      precise vec3 pixelChroma = radiance / luminance(radiance);
      drift = drift + (accvec3(chroma) - accvec3(pixelChroma));
    }
    if (colourControl) {
      precise vec3 dc = colourMean - cn.chroma;
      precise accvec3 cv = sum + colourScale * (accvec3(dc) + drift);
      sum = cv;
    }
    float pc = float(pcH);
    if (!(pc > 0.0)) continue;
    float pb = plan.bWeight > 0.0 ? bsdfPdf(plan.bm, sh.woLocal, toLocal(sh.frame, es.dir)) : 0.0;
    precise float denom = plan.cWeight * pc + plan.bWeight * pb;
    precise vec3 f = reflected(sh, es.dir, envRadiance(es.pixel)) / denom;
    precise accvec3 next = sum + accvec3(f);
    sum = next;
  }
  for (; j < end; ++j) {
    samplerStart(smp, j - plan.cutCount);
    smp.dimension = 1u;
    vec3 local = sampleBsdf(plan.bm, sh.woLocal, samplerNext2D(smp));
    float pb = bsdfPdf(plan.bm, sh.woLocal, local);
    if (!(pb > 0.0)) continue;
    vec3 wi = toWorld(sh.frame, local);
    uint pixel = envPixelOf(wi);
    uint k = cutLookup(pixel >> (2u * (scene.envOrder - scene.cutLookupLevel)));
    precise float share = (gCutCum[k + 1u] - gCutCum[k]) / total;
    precise hreal p = hreal(share);
    uint level = cutRecord(k).level;
    uint below = max(level, productLevel);
    for (uint l = level + 1u; l <= below && p > 0.0; ++l) {
      float cw[4];
      cutChildWeights(l, pixel >> (2u * (scene.envOrder - l + 1u)), cw);
      uint c = (pixel >> (2u * (scene.envOrder - l))) & 3u;
      precise float cwSum = ((cw[0] + cw[1]) + cw[2]) + cw[3];
      float wc = c == 0u ? cw[0] : c == 1u ? cw[1] : c == 2u ? cw[2] : cw[3];
      precise float q = wc / cwSum;
      p = wc > 0.0 ? p * hreal(q) : hreal(0.0);
    }
    precise hreal pcH = p * environmentPixelProbabilityBelow(below, pixel) / envPixelSolidAngle();
    float pc = float(pcH);
    precise float denom = plan.cWeight * pc + plan.bWeight * pb;
    precise vec3 f = reflected(sh, wi, envRadiance(pixel)) / denom;
    precise accvec3 next = sum + accvec3(f);
    sum = next;
  }
  return j - begin;
}

#endif
