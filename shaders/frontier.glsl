// ht-frontier (host/ht_frontier.cpp): exactly n directions over an adaptive
// frontier of HEALPix nodes, drawn as on the CPU for the same pixel and
// seed (HT_FP64; the fp32 shader keeps the masses in float). The table is
// built in frontier_table.glsl; here directions are drawn from it and the
// estimate is summed.
//
// The first batch of a pixel builds its table; every batch draws
// directions from it (GpuFrontierPoint carries the rest).
#ifndef HT_FRONTIER_GLSL
#define HT_FRONTIER_GLSL

#include "frontier_table.glsl"

// ---------------------------------------------------------------- sampling

bool frontierTouched(GpuFrontierNode nd) { return ((gFrTouched >> frontierFace(nd)) & 1u) != 0u; }
hreal frontierMass(uint k) { return frontierTouched(tableNode(k)) ? gFrPointMass.v[(k) * gFrPixels] : tableMass(k); }
uint frontierVisibility(uint k) {
  GpuFrontierNode nd = tableNode(k);
  return frontierTouched(nd) ? gFrPointClass.v[(k) * gFrPixels] : nd.visibility;
}

// The segments' masses before each, and the total.
void frontierSegments() {
  hreal total = 0.0;
  for (uint seg = 0u; seg < uint(HT_FRONTIER_SEGMENTS); ++seg) {
    gFrSegCum.v[(seg) * gFrPixels] = total;
    uint first = segStart(seg), end = segStart(seg + 1u);
    if (first == end) continue;
    if (((gFrTouched >> (seg % 12u)) & 1u) != 0u)
      total = addF(total, addF(gFrPointCum.v[(end - 1u) * gFrPixels], gFrPointMass.v[(tableOrder(end - 1u)) * gFrPixels]));
    else
      total = addF(total, subF(tableCum(end), tableCum(first)));
  }
  gFrSegCum.v[(HT_FRONTIER_SEGMENTS) * gFrPixels] = total;
  gFrTotal = total;
}

// Frontier::children: the four children's weights and classes. The
// children's classes and BRDF factors are loops of a variable count, 0
// where the parent is free or the level below the product levels, as
// llvmpipe runs all of a loop's body for its SIMD group (a loop no lane
// enters costs one pass, not four); the arrays are written at constant
// indices, which llvmpipe keeps in registers.
void frontierChildren(uint level, uint parent, uint parentClass, out hreal w[4], out uint cls[4]) {
  uint first = levelOffset(level) + 4u * parent;
  hreal v[4];
  for (uint j = 0u; j < 4u; ++j) {
    w[j] = hreal(treeAvg(first + j));
    cls[j] = parentClass;
    v[j] = 1.0;
  }
  bool product = level <= gFrProductLevel;
  if (!product && parentClass != 2u) return;
  [[dont_unroll]] for (uint j = 0u; j < (parentClass == 2u ? 4u : 0u); ++j) {
    float factor;
    uint c = frontierNodeClass(level, 4u * parent + j, gFrCaps, factor);
    [[unroll]] for (uint i = 0u; i < 4u; ++i) {
      cls[i] = i == j ? c : cls[i];
      v[i] = i == j ? hreal(factor) : v[i];
    }
  }
  hreal b[4] = hreal[4](1.0, 1.0, 1.0, 1.0);
  if (product) {
    hreal top = 0.0;
    [[dont_unroll]] for (uint j = 0u; j < 4u; ++j) {
      hreal wj = w[0];
      uint cj = cls[0];
      [[unroll]] for (uint i = 1u; i < 4u; ++i) {
        wj = i == j ? w[i] : wj;
        cj = i == j ? cls[i] : cj;
      }
      vec3 d = frontierFactorDirection(first + j);
      hreal bj = 0.0;
      if (wj > 0.0 && cj != 0u) bj = gFrLambert ? hreal(max(dot3(d, ht.n), 0.0)) : hreal(htBrdfValue(d));
      [[unroll]] for (uint i = 0u; i < 4u; ++i) b[i] = i == j ? bj : b[i];
      top = max(top, bj);
    }
    for (uint j = 0u; j < 4u; ++j) b[j] = top > 0.0 ? max(b[j], mulF(hreal(gFrBrdfFloor), top)) : hreal(1.0);
  }
  hreal p[4];
  for (uint j = 0u; j < 4u; ++j) p[j] = mulF(mulF(w[j], b[j]), v[j]);
  if (addF(addF(addF(p[0], p[1]), p[2]), p[3]) > 0.0)
    for (uint j = 0u; j < 4u; ++j) w[j] = p[j];
}

uint frontierFirstLeaf(GpuFrontierNode nd) { return nd.node << (2u * (ht.order - nd.level)); }

// Frontier::nodeOfLeaf: the node holding `leaf`, or the table's size.
uint frontierNodeOfLeaf(uint leaf) {
  uint count = tableCount();
  uint first = 0u, len = count;  // std::upper_bound on the first leaves
  while (len > 0u) {
    uint step = len / 2u;
    if (!(leaf < frontierFirstLeaf(tableNode(first + step)))) {
      first += step + 1u;
      len -= step + 1u;
    } else {
      len = step;
    }
  }
  if (first == 0u) return count;
  GpuFrontierNode nd = tableNode(first - 1u);
  uint leaves = 1u << (2u * (ht.order - nd.level));
  return leaf - frontierFirstLeaf(nd) < leaves ? first - 1u : count;
}

// Frontier::pdf.
hreal frontierPdf(uint leaf) {
  uint k = frontierNodeOfLeaf(leaf);
  if (k >= tableCount()) return 0.0;
  hreal mass = frontierMass(k);
  if (!(mass > 0.0)) return 0.0;
  GpuFrontierNode nd = tableNode(k);
  hreal p = divF(mass, gFrTotal);
  uint cls = frontierVisibility(k);
  for (uint level = nd.level + 1u; level <= ht.order; ++level) {
    uint node = leaf >> (2u * (ht.order - level));
    hreal w[4];
    uint c[4];
    frontierChildren(level, node >> 2, cls, w, c);
    hreal sum = addF(addF(addF(w[0], w[1]), w[2]), w[3]);
    hreal chosen = w[0];
    uint chosenClass = c[0];
    [[unroll]] for (uint i = 1u; i < 4u; ++i) {  // at constant indices, as in frontierSample
      chosen = (node & 3u) == i ? w[i] : chosen;
      chosenClass = (node & 3u) == i ? c[i] : chosenClass;
    }
    p = mulF(p, divF(chosen, sum));
    cls = chosenClass;
  }
  return divF(p, envPixelSolidAngle());
}

// The CDF position's "mass before" of Frontier::sample.
hreal frontierBefore(bool own, uint first, uint i) {
  return own ? gFrPointCum.v[(i) * gFrPixels] : subF(tableCum(i), tableCum(first));
}

// Frontier::sample: the leaf of the point x of the mass CDF, its direction
// (HEALPix frame) at `jitter` inside it and its density.
uint frontierSample(hreal x, vec2 jitter, out hvec3 dirHp, out hreal pdf, out uint nodeK) {
  hreal target = mulF(x, gFrTotal);
  uint above = 1u, len = uint(HT_FRONTIER_SEGMENTS);  // std::upper_bound over the segments' starts
  while (len > 0u) {
    uint step = len / 2u;
    if (!(target < gFrSegCum.v[(above + step) * gFrPixels])) {
      above += step + 1u;
      len -= step + 1u;
    } else {
      len = step;
    }
  }
  uint seg = min(above - 1u, uint(HT_FRONTIER_SEGMENTS) - 1u);
  while (seg > 0u && !(gFrSegCum.v[(seg + 1u) * gFrPixels] > gFrSegCum.v[(seg) * gFrPixels])) --seg;
  bool own = ((gFrTouched >> (seg % 12u)) & 1u) != 0u;
  uint first = segStart(seg), end = segStart(seg + 1u);
  hreal r = subF(target, gFrSegCum.v[(seg) * gFrPixels]);
  uint lo = first, hi = end;
  while (hi - lo > 1u) {
    uint mid = (lo + hi) / 2u;
    if (frontierBefore(own, first, mid) <= r)
      lo = mid;
    else
      hi = mid;
  }
  uint i = lo;
  while (i > first && !(frontierMass(tableOrder(i)) > 0.0)) --i;
  while (!(frontierMass(tableOrder(i)) > 0.0)) ++i;
  uint k = tableOrder(i);
  nodeK = k;
  hreal mass = frontierMass(k);
  hreal t = clamp(divF(subF(r, frontierBefore(own, first, i)), mass), hreal(0.0), hreal(1.0));
  hreal p = divF(mass, gFrTotal);
  GpuFrontierNode nd = tableNode(k);
  uint node = nd.node;
  uint cls = frontierVisibility(k);
  for (uint level = nd.level + 1u; level <= ht.order; ++level) {
    hreal a[4];
    uint c[4];
    frontierChildren(level, node, cls, a, c);
    hreal sum = addF(addF(addF(a[0], a[1]), a[2]), a[3]);
    hreal want = mulF(t, sum);
    // The child whose share of the weights holds want, by selects at
    // constant indices (llvmpipe reads an array at a lane's own index lane
    // by lane): past every child with no weight or wholly below want, then
    // back to the last child with weight.
    hreal acc = 0.0;
    uint j = 0u;
    bool on = true;
    [[unroll]] for (uint i = 0u; i < 3u; ++i) {
      on = on && (a[i] <= 0.0 || addF(acc, a[i]) <= want);
      acc = on ? addF(acc, a[i]) : acc;
      j = on ? i + 1u : j;
    }
    uint pick = j;
    [[unroll]] for (uint i = 0u; i < 4u; ++i) pick = i <= j && a[i] > 0.0 ? i : pick;
    hreal chosen = a[0];
    uint chosenClass = c[0];
    [[unroll]] for (uint i = 1u; i < 4u; ++i) {
      chosen = pick == i ? a[i] : chosen;
      chosenClass = pick == i ? c[i] : chosenClass;
    }
    t = clamp(divF(subF(want, acc), chosen), hreal(0.0), hreal(1.0));
    p = mulF(p, divF(chosen, sum));
    node = 4u * node + pick;
    cls = chosenClass;
  }
  pdf = divF(p, envPixelSolidAngle());
  dirHp = pixToVec(ht.order, node, jitter.x, jitter.y);
  return node;
}

// Frontier::colourOf: kappa x the chroma of a direction drawn in node k
// that reached `leaf`.
hvec3 frontierColourOf(uint k, uint leaf) {
  bool exact = gFrShared || tableNode(k).level >= gFrProductLevel;
  hvec3 chroma = frontierVisibility(k) == 1u && exact ? frontierLeafChroma(envRadiance(leaf)) : hvec3(frontierChroma(k, gFrShared));
  return frontierTimesKappa(frontierKappa(k, gFrShared), chroma);
}

// An own table's sums of sumFaceColours, face by face.
hvec3 frontierOwnColourSum(out hreal colourMass) {
  hvec3 colourSum = hvec3(0.0);
  colourMass = 0.0;
  for (uint f = 0u; f < 12u; ++f) {
    hvec3 colour = hvec3(0.0);
    hreal mass = 0.0;
    for (uint k = faceStart(f); k < faceStart(f + 1u); ++k) {
      colour = frontierAddColour(colour, tableMass(k), k, tableNode(k).visibility, false);
      mass = addF(mass, tableMass(k));
    }
    colourSum = frontierAdd3(colourSum, colour);
    colourMass = addF(colourMass, mass);
  }
  return colourSum;
}

// ---------------------------------------------------------------- estimate

// frontierLobeCount's S and D (lobeAndDiffuse).
void frontierLobeAndDiffuse(GpuMaterial m, out hreal lobeOut, out hreal diffuseOut) {
  precise float f0 = luminance(m.specular);
  precise float t = 1.0 - clamp(ht.woLocal.z, 0.0, 1.0);
  precise float reflectance = m.type == HT_MATERIAL_GGX ? f0 + (1.0 - f0) * (t * t * t * t * t) : f0;
  uint level = min(uint(HT_FRONTIER_LOBE_LEVEL), scene.envOrder);
  float radiance = treeAvg(levelOffset(level) + vecToPix(level, hvec3(ht.mirror)));
  precise hreal lobe = hreal(reflectance) * hreal(radiance);
  precise hreal diffuse = hreal(luminance(m.diffuse)) * hreal(kInvPi) * gFrTotal;
  lobeOut = lobe;
  diffuseOut = diffuse;
}
// frontierLobeCount: the n_s of n directions that sample the specular lobe
// of a flat surface, whose table is its diffuse lobe's.
uint frontierLobeCount(GpuMaterial m, uint n) {
  hreal lobe, diffuse;
  frontierLobeAndDiffuse(m, lobe, diffuse);
  if (!(lobe > 0.0) || n < 2u) return 0u;
  precise hreal x = hreal(n) * lobe / (lobe + diffuse);
  hreal whole = floor(x);
  uint ns = uint(whole) + (subF(x, whole) >= 0.5 ? 1u : 0u);
  return clamp(ns, 1u, n - 1u);
}
// frontierLobeMixture: for one direction, the probability that it samples
// the lobe.
hreal frontierLobeMixture(GpuMaterial m) {
  hreal lobe, diffuse;
  frontierLobeAndDiffuse(m, lobe, diffuse);
  if (!(lobe > 0.0)) return 0.0;
  precise hreal share = lobe / (lobe + diffuse);
  return clamp(share, hreal(HT_FRONTIER_MIXTURE_MIN), hreal(1.0 - HT_FRONTIER_MIXTURE_MIN));
}

// The table is the diffuse lobe's shared one and the BRDF technique samples
// the specular lobe alone (Frontier::specularApart).
bool frontierSpecularApart(GpuMaterial material, uint table) {
  return table != kFrontierNone && material.type != HT_MATERIAL_LAMBERT;
}

// Points the globals at the pixel's scratch.
void frontierBind(uint slot) {
  uint x = slot % pc.tileWidth, y = slot / pc.tileWidth;
  uint block = y * ((pc.tileWidth + HT_FRONTIER_LANES - 1u) / HT_FRONTIER_LANES) + x / HT_FRONTIER_LANES;
  gFrBase = pc.frontierScratch + uint64_t(block) * uint64_t(HT_FRONTIER_LANES * gFs.pixelBytes);
  gFrPixels = HT_FRONTIER_LANES;
  gFrSlot = x % HT_FRONTIER_LANES;
}

// The first batch: the point's table and everything the batches' directions
// read. False when there is nothing to sample.
bool frontierBegin(vec3 position, vec3 normal, vec3 wo, GpuMaterial material, bool planar, uint slot, uint n,
                   inout uint rng, inout uint htNodes) {
  if (scene.envHasLight == 0u || n == 0u) return false;
  frontierSettings();
  htInit(position, normal, wo, material);
  frontierCaps(position, normal);
  frontierBind(slot);
  gFrTouched = 0u;
  uint table = planar && ht.woLocal.z > 0.0 ? frontierSharedTable() : kFrontierNone;
  gFrProductLevel = table != kFrontierNone ? gFs.productLevel : frontierProductLevel();
  gFrLambert = material.type == HT_MATERIAL_LAMBERT || table != kFrontierNone;
  hvec3 colourSum = hvec3(0.0);
  hreal colourMass = 0.0;
  if (table != kFrontierNone) {
    frontierUseShared(table);
    colourSum = frontierApplyCaps(table, colourMass);
  } else {
    frontierRefine(n);
    htNodes += 12u + 4u * tableWord(kFrontierSplits);
    if ((gFrFlags & HT_FRONTIER_COLOUR_CONTROL) != 0u) colourSum = frontierOwnColourSum(colourMass);
  }
  frontierSegments();
  if (!(gFrTotal > 0.0)) return false;
  GpuFrontierPoint pt;
  pt.table = table;
  pt.touched = gFrTouched;
  pt.nb = frontierSpecularApart(material, table) ? frontierLobeCount(material, n) : tableWord(kFrontierBrdfCount);
  pt.nt = n - pt.nb;
  pt.total = hrealToBits(gFrTotal);
  pt.u = hrealToBits(hreal(rngNext(rng)));
  // Frontier::colourAverage.
  FrontierReals store = frontierReals(gFs.offColourAverage);
  bool some = colourMass > 0.0;
  store.v[0u * gFrPixels] = some ? divF(colourSum.x, colourMass) : hreal(0.0);
  store.v[1u * gFrPixels] = some ? divF(colourSum.y, colourMass) : hreal(0.0);
  store.v[2u * gFrPixels] = some ? divF(colourSum.z, colourMass) : hreal(0.0);
  frontierPoint().v[0] = pt;
  return true;
}

// A batch's directions: the point as the first batch left it.
GpuFrontierPoint frontierResume(vec3 position, vec3 normal, vec3 wo, GpuMaterial material, uint slot) {
  frontierSettings();
  htInit(position, normal, wo, material);
  frontierCaps(position, normal);
  frontierBind(slot);
  GpuFrontierPoint pt = frontierPoint().v[0];
  gFrProductLevel = pt.table != kFrontierNone ? gFs.productLevel : frontierProductLevel();
  gFrLambert = material.type == HT_MATERIAL_LAMBERT || pt.table != kFrontierNone;
  if (pt.table != kFrontierNone) {
    frontierUseShared(pt.table);
    frontierDropOwnPlane();
  } else {
    frontierUseOwn();
  }
  gFrTouched = pt.touched;
  gFrTotal = hrealFromBits(pt.total);
  FrontierReals store = frontierReals(gFs.offColourAverage);
  gFrColourR = store.v[0u * gFrPixels];
  gFrColourG = store.v[1u * gFrPixels];
  gFrColourB = store.v[2u * gFrPixels];
  return pt;
}

// A direction's term f / (n_t p_t + n_b p_b), `denom` the sum.
void frontierAddDirection(Shading sh, vec3 wi, uint leaf, hreal denom, inout accvec3 sum) {
  vec3 f = reflected(sh, wi, envRadiance(leaf));
  if (f == vec3(0.0)) return;
  precise accvec3 total = sum + accvec3(f) / denom;
  sum = total;
}

// Directions [begin, end) of the n: the table's first, then the BRDF's,
// each weighted by the balance heuristic over the two counts.
uint frontierSamples(Shading sh, GpuFrontierPoint pt, uint begin, uint end, inout Sampler smp, inout accvec3 sum,
                     inout uint directions) {
  hreal u = hrealFromBits(pt.u);
  // The techniques' weights: their counts, or for one direction with the
  // lobe apart the mixture's probabilities, u choosing the technique.
  hreal wt = hreal(pt.nt), wb = hreal(pt.nb);
  uint nt = pt.nt;
  GpuMaterial bm = sh.material;
  hreal q = 0.0;
  if (frontierSpecularApart(sh.material, pt.table)) {
    bm.diffuse = vec3(0.0);
    bm.specularProbability = luminance(bm.specular) > 0.0 ? 1.0 : 0.0;  // specularLobeProbability
    if (pt.nt + pt.nb == 1u) q = frontierLobeMixture(sh.material);
  }
  if (q > 0.0) {
    wt = subF(hreal(1.0), q);
    wb = q;
    if (u < q) {
      nt = 0u;
    } else {
      precise hreal rest = (u - q) / (hreal(1.0) - q);
      u = rest;
    }
  }
  // The control variate's M / n, and a shared table's albedo / pi (estimateHtFrontier).
  hvec3 colourScale = hvec3(0.0);
  if ((gFrFlags & HT_FRONTIER_COLOUR_CONTROL) != 0u) {
    vec3 d = sh.material.diffuse;
    colourScale = pt.table != kFrontierNone
                      ? hvec3(mulF(hreal(d.x), hreal(kInvPi)), mulF(hreal(d.y), hreal(kInvPi)), mulF(hreal(d.z), hreal(kInvPi)))
                      : hvec3(1.0);
    // With the mixture a table direction comes with probability wt.
    hreal n = q > 0.0 ? mulF(hreal(pt.nt + pt.nb), wt) : hreal(pt.nt + pt.nb);
    colourScale = hvec3(divF(mulF(colourScale.x, gFrTotal), n), divF(mulF(colourScale.y, gFrTotal), n),
                        divF(mulF(colourScale.z, gFrTotal), n));
  }
  bool colourControl = colourScale != hvec3(0.0);
  // The table's directions, then the BRDF's, in loops of their own: llvmpipe
  // runs all of a loop's body for its SIMD group.
  uint j = begin;
  for (; j < min(end, nt); ++j) {
    directions += 1u;
    samplerStart(smp, j);
    precise hreal x = (hreal(j) + u) / hreal(nt);
    vec2 jitter = samplerNext2D(smp);
    hvec3 hp;
    uint k;
    hreal ptable;
    uint leaf = frontierSample(x, jitter, hp, ptable, k);
    if (colourControl) {
      hvec3 v = frontierColourOf(k, leaf);
      hvec3 d = hvec3(subF(gFrColourR, v.x), subF(gFrColourG, v.y), subF(gFrColourB, v.z));
      sum = frontierAdd3(sum, hvec3(mulF(colourScale.x, d.x), mulF(colourScale.y, d.y), mulF(colourScale.z, d.z)));
    }
    vec3 wi = fromHealpixFrame(hp);
    hreal pb = wb > 0.0 ? hreal(bsdfPdf(bm, sh.woLocal, toLocal(sh.frame, wi))) : hreal(0.0);
    precise hreal denom = wt * ptable + wb * pb;
    frontierAddDirection(sh, wi, leaf, denom, sum);
  }
  for (; j < end; ++j) {
    directions += 1u;
    samplerStart(smp, j - nt);
    smp.dimension = 1u;
    vec3 local = sampleBsdf(bm, sh.woLocal, samplerNext2D(smp));
    float pdf = bsdfPdf(bm, sh.woLocal, local);
    if (!(pdf > 0.0)) continue;
    vec3 wi = toWorld(sh.frame, local);
    uint leaf = envPixelOf(wi);
    hreal ptable = frontierPdf(leaf);
    precise hreal denom = wt * ptable + wb * hreal(pdf);
    frontierAddDirection(sh, wi, leaf, denom, sum);
  }
  return j - begin;
}

#endif
