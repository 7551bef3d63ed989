// ht-frontier's table (host/ht_frontier.cpp): the caps and node classes,
// colour, a point's own table and a plane's shared one with the point's
// caps applied; frontier.glsl draws directions from it.
//
// A point's own table is refined in its scratch (GpuFrontierScene's
// offsets). The scratch is cut into blocks of HT_FRONTIER_LANES pixels of a
// tile row, each block laid out element by element with its pixels side by
// side (element k of its pixel j at k x HT_FRONTIER_LANES + j), so that the
// invocations of a SIMD group read neighbouring words and a block's arrays
// stay within few pages: candidates and a binary heap on (priority, index), whose largest
// element is unique, so it splits the nodes std::pop_heap would, in the same
// order. The nodes the refinement leaves unsplit are read out depth first,
// which is the nested index's order the CPU sorts them into. A flat
// surface takes its plane's shared Lambert table (built on the host) and
// applies its own caps to the faces they reach; with a specular lobe, the
// lobe is sampled apart.
#ifndef HT_FRONTIER_TABLE_GLSL
#define HT_FRONTIER_TABLE_GLSL

#include "ht.glsl"

#define gFs scene.frontier.f
#define kFrontierNone 0xFFFFFFFFu

// The pixel's scratch: its block, the stride of its arrays (the block's
// pixels) and its place in the block.
uint64_t gFrBase;
uint gFrPixels, gFrSlot;
// The table it samples, a shared one (gFrShared: table gFrTable, its nodes
// from gFrNodeBase and its prefix sums from gFrCumBase in the shared
// arrays) or the pixel's own: its header (GpuFrontierHeader's words),
// nodes, order, masses and prefix sums, each element gFrStride apart (the
// block's pixels for an own table, 1 for a shared one). The arrays'
// addresses are made where they are read, from the offsets (alike for
// every invocation) and bases, rather than held per invocation as 64-bit
// addresses, which took a GPU's compiler 40 more registers for the
// pipeline (docs/ht.md, "On a real GPU").
uint gFrTable, gFrNodeBase, gFrCumBase;
uint gFrOffHeader, gFrOffNodes, gFrOffOrder, gFrOffMass, gFrOffCum, gFrOffKappa;
uint64_t gFrShHeaders, gFrShNodes, gFrShOrder, gFrShMass, gFrShCum, gFrShColour;
#define kFrontierHeaderBytes uint64_t(4 * (HT_FRONTIER_SEGMENTS + 20))
#define gFrHeader \
  (gFrShared ? FrontierUints(gFrShHeaders + uint64_t(gFrTable) * kFrontierHeaderBytes) : frontierUints(gFrOffHeader))
#define gFrNodes (gFrShared ? FrontierNodes(gFrShNodes + uint64_t(gFrNodeBase) * 24ul) : frontierNodes(gFrOffNodes))
#define gFrOrder (gFrShared ? FrontierUints(gFrShOrder + uint64_t(gFrNodeBase) * 4ul) : frontierUints(gFrOffOrder))
#define gFrMass \
  (gFrShared ? FrontierReals(gFrShMass + uint64_t(gFrNodeBase) * uint64_t(kFrontierRealBytes)) : frontierReals(gFrOffMass))
#define gFrCum \
  (gFrShared ? FrontierReals(gFrShCum + uint64_t(gFrCumBase) * uint64_t(kFrontierRealBytes)) : frontierReals(gFrOffCum))
// An own table's FrontierNode::kappa (a shared one's are in gFrColour).
#define gFrKappa frontierVec3s(gFrOffKappa)
#define gFrColour FrontierColourNodes(gFrShColour + uint64_t(gFrNodeBase) * 28ul)
#define gFrStride (gFrShared ? 1u : gFrPixels)
// The point's masses, classes and prefix sums over a shared table on the
// faces in gFrTouched, and the mass of the segments before each.
uint gFrOffPointMass, gFrOffPointCum, gFrOffSegCum, gFrOffPointClass;
#define gFrPointMass frontierReals(gFrOffPointMass)
#define gFrPointCum frontierReals(gFrOffPointCum)
#define gFrSegCum frontierReals(gFrOffSegCum)
#define gFrPointClass frontierUints(gFrOffPointClass)
uint gFrTouched;
hreal gFrTotal;
bool gFrLambert;
// The table is a shared one (its colours in gFrColour), and the point's
// Frontier::colourAverage.
bool gFrShared;
hreal gFrColourR, gFrColourG, gFrColourB;

// The settings read per node, copied once from GpuFrontierScene (read
// through a device address, which llvmpipe loads lane by lane at each
// read): the levels' cone radii (cos, sin), the floor of a partly
// covered node's factor, the flags, the BRDF floor, the coarse ratio, the
// refinements; and the scratch arrays' offsets and the shared tables'
// arrays, above.
float gFrLevelCos[HT_MAX_ORDER + 2];
float gFrLevelSin[HT_MAX_ORDER + 2];
float gFrMinPartial;
uint gFrFlags;
float gFrBrdfFloor, gFrCoarseRatio;
uint gFrRefinements;
void frontierSettings() {
  for (uint l = 0u; l <= uint(HT_MAX_ORDER) + 1u; ++l) {
    gFrLevelCos[l] = gFs.levelCosRadius[l];
    gFrLevelSin[l] = gFs.levelSinRadius[l];
  }
  gFrMinPartial = gFs.minPartialVisibility;
  gFrFlags = gFs.flags;
  gFrBrdfFloor = gFs.brdfFloor;
  gFrCoarseRatio = gFs.coarseRatio;
  gFrRefinements = gFs.refinements;
  gFrOffPointMass = gFs.offPointMass;
  gFrOffPointCum = gFs.offPointCum;
  gFrOffSegCum = gFs.offSegCum;
  gFrOffPointClass = gFs.offPointClass;
  gFrOffHeader = gFs.offHeader;
  gFrOffNodes = gFs.offNodes;
  gFrOffOrder = gFs.offOrder;
  gFrOffMass = gFs.offMass;
  gFrOffCum = gFs.offCum;
  gFrOffKappa = gFs.offKappa;
  FrontierSceneRef s = scene.frontier;
  gFrShHeaders = uint64_t(s.f.sharedHeaders);
  gFrShNodes = uint64_t(s.f.sharedNodes);
  gFrShOrder = uint64_t(s.f.sharedOrder);
  gFrShMass = uint64_t(s.f.sharedMass);
  gFrShCum = uint64_t(s.f.sharedCum);
  gFrShColour = uint64_t(s.f.sharedColour);
}

// lightCaps: per cap slot (one per sphere and plane, bindings.glsl's
// kCapSlots) its axis and the sine and cosine of its half-angle less the
// margin. gFrCaps: the slots the point applies (bits).
vec3 gFrCapAxis[HT_MAX_CAPS];
float gFrCapSin[HT_MAX_CAPS];
float gFrCapCos[HT_MAX_CAPS];
uint gFrCaps;

// The pixel's first element of the scratch array at `offset` (bytes per
// pixel before it), of elements of `size` bytes.
uint64_t frontierArray(uint offset, uint size) {
  return gFrBase + uint64_t(offset * uint(HT_FRONTIER_LANES) + gFrSlot * size);
}
#if HT_FP64
#define kFrontierRealBytes 8u
#else
#define kFrontierRealBytes 4u
#endif
FrontierReals frontierReals(uint offset) { return FrontierReals(frontierArray(offset, kFrontierRealBytes)); }
FrontierUints frontierUints(uint offset) { return FrontierUints(frontierArray(offset, 4u)); }
FrontierNodes frontierNodes(uint offset) { return FrontierNodes(frontierArray(offset, 24u)); }
FrontierVec3s frontierVec3s(uint offset) { return FrontierVec3s(frontierArray(offset, 12u)); }
FrontierPoints frontierPoint() { return FrontierPoints(gFrBase + uint64_t(gFrSlot) * 32ul); }

// The table's header words (GpuFrontierHeader, segStart first) and arrays,
// read; the own table's are written through gFrHeader and the rest directly.
#define kFrontierFaceStart (HT_FRONTIER_SEGMENTS + 1)
#define kFrontierCount (kFrontierFaceStart + 13)
#define kFrontierSplits (kFrontierCount + 1)
#define kFrontierBrdfCount (kFrontierCount + 2)
#define kFrontierNodeBase (kFrontierCount + 3)
#define kFrontierCumBase (kFrontierCount + 4)
uint tableWord(uint w) { return gFrHeader.v[w * gFrStride]; }
uint segStart(uint seg) { return tableWord(seg); }
uint faceStart(uint f) { return tableWord(kFrontierFaceStart + f); }
uint tableCount() { return tableWord(kFrontierCount); }
GpuFrontierNode tableNode(uint k) { return gFrNodes.v[k * gFrStride]; }
uint tableOrder(uint i) { return gFrOrder.v[i * gFrStride]; }
hreal tableMass(uint k) { return gFrMass.v[k * gFrStride]; }
hreal tableCum(uint i) { return gFrCum.v[i * gFrStride]; }

precise hreal addF(hreal a, hreal b) { return a + b; }
precise hreal subF(hreal a, hreal b) { return a - b; }
precise hreal mulF(hreal a, hreal b) { return a * b; }
precise hreal divF(hreal a, hreal b) { return a / b; }

void frontierAddCap(uint k, vec3 axis, float s0) {
  precise float c0 = sqrt(1.0 - s0 * s0);
  precise float sinA = s0 * gFs.capCosMargin - c0 * gFs.capSinMargin;
  precise float cosA = c0 * gFs.capCosMargin + s0 * gFs.capSinMargin;
  if (!(sinA > 0.0)) return;
  gFrCapAxis[k] = axis;
  gFrCapSin[k] = sinA;
  gFrCapCos[k] = cosA;
  gFrCaps |= 1u << k;
}

// occluders() and lightCaps, seen from the shadow rays' origin. The loop
// of caps.glsl's occluderSlots, inline: its arrays of every slot's axis and
// sine, alive at once, raised this pipeline's peak from 192 to 216 VGPRs
// under RADV (tests/shader_stats_test.sh).
void frontierCaps(vec3 position, vec3 normal) {
  gFrCaps = 0u;
  if ((gFrFlags & HT_FRONTIER_VISIBILITY) == 0u) return;
  precise vec3 origin = offsetRayOrigin(position, normal);
  const uint capped = capSpheres(origin, normal);
  for (uint j = 0u; j < capped; ++j) {
    vec3 axis;
    float sine;
    if (sphereCap(j, origin, axis, sine)) frontierAddCap(j, axis, sine);
  }
  for (uint k = 0u; k < scene.planeCount; ++k) frontierAddCap(capped + k, planeCapAxis(k, origin), 1.0);
}

// A cap's thresholds at a level (LightCap::cosInside, cosOutside).
precise float frontierCosInside(uint k, float cR, float sR) {
  precise float inner = gFrCapSin[k] * cR - gFrCapCos[k] * sR;
  precise float c = gFrCapCos[k] * cR + gFrCapSin[k] * sR;
  return inner > 0.0 ? c : 2.0;
}
precise float frontierCosOutside(uint k, float cR, float sR) { return gFrCapCos[k] * cR - gFrCapSin[k] * sR; }

// frontierVisibility and frontierNodeVisibility: the class of node `node`
// of `level` under the caps in `caps` (0 inside one, 1 outside all, 2 partly
// covered) and its factor in the density, a coarse partly covered node's
// the mean of its children's factors under the caps that cover it in part.
// The node and its children are passes of one loop, one pass for all but
// the coarse partly covered nodes: llvmpipe runs all of a loop's body for
// its SIMD group, so that a loop of its own for the children would cost a
// pass for every node.
uint frontierNodeClass(uint level, uint node, uint caps, out float factor) {
  uint cls = 1u, partialCaps = 0u, probes = 1u;
  factor = 1.0;
  precise float share = 0.0;
  [[dont_unroll]] for (uint j = 0u; j < probes; ++j) {
    bool self = j == 0u;
    uint at = self ? level : level + 1u;
    vec3 centre = htCenter(self ? levelOffset(level) + node : levelOffset(level + 1u) + 4u * node + j - 1u);
    float cR = gFrLevelCos[at], sR = gFrLevelSin[at];
    uint probeCaps = self ? caps : partialCaps;
    bool inside = false;
    uint partial = 0u;
    precise float visible = 1.0;
    [[unroll]] for (uint k = 0u; k < kCapSlots; ++k) {
      if (((probeCaps >> k) & 1u) == 0u) continue;
      precise float d = dot3(centre, gFrCapAxis[k]);
      precise float inner = frontierCosInside(k, cR, sR), outside = frontierCosOutside(k, cR, sR);
      if (d >= inner) {
        inside = true;
      } else if (d > outside) {
        partial |= 1u << k;
        visible = min(visible, 1.0 - min((d - outside) / (min(inner, 1.0) - outside), 1.0));
      }
    }
    if (self) {
      cls = inside ? 0u : partial != 0u ? 2u : 1u;
      factor = inside ? 0.0 : partial != 0u ? max(visible, gFrMinPartial) : 1.0;
      partialCaps = partial;
      probes = cls == 2u && level <= uint(HT_FRONTIER_SHARE_LEVEL) && level < ht.order ? 5u : 1u;
    } else {
      share += inside ? 0.0 : partial != 0u && visible > 0.0 ? max(visible, gFrMinPartial) : visible;
    }
  }
  precise float quarter = 0.25 * share;
  if (probes == 5u) factor = max(quarter, gFrMinPartial);
  return cls;
}

uint frontierColourBin(uint i) {
  if ((gFrFlags & HT_FRONTIER_COLOUR_ORDER) == 0u) return 0u;
  uint word = kTexels ? texelFetch(frontierBinsTexels, int(i >> 2)).x : gFs.bins.v[i >> 2];
  return (word >> (8u * (i & 3u))) & 0xFFu;
}
uint frontierFace(GpuFrontierNode nd) { return nd.node >> (2u * nd.level); }
uint frontierSegment(GpuFrontierNode nd) {
  return frontierColourBin(levelOffset(nd.level) + nd.node) * 12u + frontierFace(nd);
}

// ---------------------------------------------------------------- colour

// frontierLeafChroma: a leaf's radiance over its luminance.
hvec3 frontierLeafChroma(vec3 radiance) {
  float l = luminance(radiance);
  if (!(l > 0.0)) return hvec3(0.0);
  return hvec3(divF(hreal(radiance.x), hreal(l)), divF(hreal(radiance.y), hreal(l)), divF(hreal(radiance.z), hreal(l)));
}

// A node's chroma (nodeChroma): FrontierColours::chroma above the leaves.
vec3 frontierNodeChroma(uint level, uint node) {
  if (level >= ht.order) return vec3(frontierLeafChroma(envRadiance(node)));
  uint i = levelOffset(level) + node;
  if (kTexels) return texelVec3(frontierChromaTexels, i);
  return gFs.chroma[i >> HT_HT_VEC3_CHUNK_SHIFT].v[i & ((1u << HT_HT_VEC3_CHUNK_SHIFT) - 1u)];
}

// frontierFactorDirection: node i's centroid above the leaves, a leaf's
// centre.
vec3 frontierFactorDirection(uint i) {
  if (i >= levelOffset(ht.order)) return htCenter(i);
  if (kTexels) return texelVec3(frontierCentroidTexels, i);
  return gFs.centroids[i >> HT_HT_VEC3_CHUNK_SHIFT].v[i & ((1u << HT_HT_VEC3_CHUNK_SHIFT) - 1u)];
}

// FrontierNode::chroma, descentChroma and kappa of the table's node k, on
// a shared table or an own one (whose node's descent is exact for colour
// only below the product levels, where its mean is its chroma). `onShared`
// is a constant where the caller knows it: llvmpipe would run both sides.
vec3 frontierChroma(uint k, bool onShared) {
  if (onShared) return gFrColour.v[k].chroma;
  GpuFrontierNode nd = tableNode(k);
  return frontierNodeChroma(nd.level, nd.node);
}
vec3 frontierDescentChroma(uint k, bool onShared) { return onShared ? gFrColour.v[k].descent : frontierChroma(k, false); }
vec3 frontierKappa(uint k, bool onShared) { return onShared ? vec3(gFrColour.v[k].kappa) : gFrKappa.v[k * gFrStride]; }

// colourMeanOf: the mean chroma of the directions node k of class cls draws.
vec3 frontierColourMean(uint k, uint cls, bool onShared) {
  return cls == 1u ? frontierDescentChroma(k, onShared) : frontierChroma(k, onShared);
}

// kappa x a chroma (Frontier::colourOf, colourMean), in the reals' precision.
hvec3 frontierTimesKappa(vec3 kappa, hvec3 chroma) {
  return hvec3(mulF(hreal(kappa.x), chroma.x), mulF(hreal(kappa.y), chroma.y), mulF(hreal(kappa.z), chroma.z));
}

// sumFaceColours' terms: mass x kappa x the mean chroma of node k of class
// cls, added to `acc`.
hvec3 frontierAddColour(hvec3 acc, hreal mass, uint k, uint cls, bool onShared) {
  hvec3 mean = frontierTimesKappa(frontierKappa(k, onShared), hvec3(frontierColourMean(k, cls, onShared)));
  return hvec3(addF(acc.x, mulF(mass, mean.x)), addF(acc.y, mulF(mass, mean.y)), addF(acc.z, mulF(mass, mean.z)));
}
hvec3 frontierAdd3(hvec3 a, hvec3 b) { return hvec3(addF(a.x, b.x), addF(a.y, b.y), addF(a.z, b.z)); }

// ---------------------------------------------------------------- own table

// The refinement's candidates: a node, its mass, and in `visibility` above
// its class: bit 3 split, bits 4-6 its children's count, bits 8- the first.
uint gFrOffCand, gFrOffCandMass, gFrOffCandKappa, gFrOffHeapKey, gFrOffHeapIndex;
#define gFrCand frontierNodes(gFrOffCand)
#define gFrCandMass frontierReals(gFrOffCandMass)
#define gFrCandKappa frontierVec3s(gFrOffCandKappa)
#define gFrHeapKey frontierReals(gFrOffHeapKey)
#define gFrHeapIndex frontierUints(gFrOffHeapIndex)
uint gFrCandCount, gFrHeapSize;
float gFrLobeFloor;      // frontierLobeFloor of the point's material
uint gFrProductLevel;    // Frontier's productLevel_: frontierProductLevel, or the option's for a shared table

bool frontierHeapLess(hreal ka, uint ia, hreal kb, uint ib) { return ka < kb || (ka == kb && ia < ib); }

void frontierHeapPush(hreal key, uint index) {
  uint i = gFrHeapSize++;
  while (i > 0u) {
    uint parent = (i - 1u) / 2u;
    hreal pk = gFrHeapKey.v[(parent) * gFrPixels];
    uint pi = gFrHeapIndex.v[(parent) * gFrPixels];
    if (!frontierHeapLess(pk, pi, key, index)) break;
    gFrHeapKey.v[(i) * gFrPixels] = pk;
    gFrHeapIndex.v[(i) * gFrPixels] = pi;
    i = parent;
  }
  gFrHeapKey.v[(i) * gFrPixels] = key;
  gFrHeapIndex.v[(i) * gFrPixels] = index;
}

uint frontierHeapPop() {
  uint top = gFrHeapIndex.v[(0) * gFrPixels];
  --gFrHeapSize;
  hreal key = gFrHeapKey.v[(gFrHeapSize) * gFrPixels];
  uint index = gFrHeapIndex.v[(gFrHeapSize) * gFrPixels];
  uint i = 0u;
  for (;;) {
    uint c = 2u * i + 1u;
    if (c >= gFrHeapSize) break;
    if (c + 1u < gFrHeapSize &&
        frontierHeapLess(gFrHeapKey.v[(c) * gFrPixels], gFrHeapIndex.v[(c) * gFrPixels], gFrHeapKey.v[(c + 1u) * gFrPixels], gFrHeapIndex.v[(c + 1u) * gFrPixels]))
      ++c;
    if (!frontierHeapLess(key, index, gFrHeapKey.v[(c) * gFrPixels], gFrHeapIndex.v[(c) * gFrPixels])) break;
    gFrHeapKey.v[(i) * gFrPixels] = gFrHeapKey.v[(c) * gFrPixels];
    gFrHeapIndex.v[(i) * gFrPixels] = gFrHeapIndex.v[(c) * gFrPixels];
    i = c;
  }
  if (gFrHeapSize > 0u) {
    gFrHeapKey.v[(i) * gFrPixels] = key;
    gFrHeapIndex.v[(i) * gFrPixels] = index;
  }
  return top;
}

// refine's push with Frontier::build's factor.
void frontierPush(uint level, uint node, uint parentClass, uint parent) {
  uint i = levelOffset(level) + node;
  float avg = treeAvg(i);
  if (!(avg > 0.0)) return;
  float diffuse;
  float bound = htBrdfBoundParts(i, diffuse);
  if (!(bound > 0.0)) return;
  float vis = 1.0;
  uint cls = parentClass;
  if ((gFrFlags & HT_FRONTIER_VISIBILITY) == 0u) {
    cls = 1u;
  } else if (cls == 2u) {
    cls = frontierNodeClass(level, node, gFrCaps, vis);
    if (cls == 0u) return;
  }
  // The control variate's kappa: the BRDF's colour where its factor is read.
  vec3 f = htBrdfColour(frontierFactorDirection(i));
  float value = luminance(f);
  precise float floor = gFrBrdfFloor * diffuse + gFrLobeFloor * (bound - diffuse);
  float top = max(value, floor);
  precise vec3 kappa = top > 0.0 ? vec3(f.x / top, f.y / top, f.z / top) : vec3(0.0);
  precise float c = top * vis;
  precise hreal energy = hreal(avg) * htPixelSolidAngle(level);
  precise hreal spread = max(hreal(0.0), hreal(bound) - hreal(c));
  precise hreal priority = level < ht.order ? energy * spread * spread / hreal(c) : hreal(0.0);
  uint k = gFrCandCount++;
  gFrCand.v[(k) * gFrPixels] = GpuFrontierNode(level, node, bound, value, cls, parent);
  gFrCandMass.v[(k) * gFrPixels] = mulF(energy, hreal(c));
  gFrCandKappa.v[(k) * gFrPixels] = kappa;
  if (priority > 0.0) frontierHeapPush(priority, k);
}

// The table's order, prefix sums, coarse share and n_b once its nodes and
// masses are in place along the nested index.
void frontierFinishTable(uint count, uint n) {
  FrontierUints next = gFrHeapIndex;  // free once refined
  for (uint f = 0u; f <= 12u; ++f) gFrHeader.v[(kFrontierFaceStart + f) * gFrStride] = 0u;
  for (uint s = 0u; s <= uint(HT_FRONTIER_SEGMENTS); ++s) gFrHeader.v[(s) * gFrStride] = 0u;
  for (uint k = 0u; k < count; ++k) {
    GpuFrontierNode nd = tableNode(k);
    ++gFrHeader.v[(kFrontierFaceStart + frontierFace(nd) + 1u) * gFrStride];
    ++gFrHeader.v[(frontierSegment(nd) + 1u) * gFrStride];
  }
  for (uint f = 0u; f < 12u; ++f) gFrHeader.v[(kFrontierFaceStart + f + 1u) * gFrStride] += faceStart(f);
  for (uint s = 0u; s < uint(HT_FRONTIER_SEGMENTS); ++s) {
    gFrHeader.v[(s + 1u) * gFrStride] += segStart(s);
    next.v[(s) * gFrPixels] = segStart(s);
  }
  for (uint k = 0u; k < count; ++k) {
    uint s = frontierSegment(tableNode(k));
    gFrOrder.v[(next.v[(s) * gFrPixels]) * gFrStride] = k;
    ++next.v[(s) * gFrPixels];
  }
  hreal total = 0.0, coarse = 0.0;
  for (uint i = 0u; i < count; ++i) {
    uint k = tableOrder(i);
    GpuFrontierNode nd = tableNode(k);
    hreal mass = tableMass(k);
    gFrCum.v[(i) * gFrStride] = total;
    total = addF(total, mass);
    precise float coarseAt = gFrCoarseRatio * nd.brdfCentre;
    if (nd.brdfBound > coarseAt) coarse = addF(coarse, mass);
  }
  gFrCum.v[(count) * gFrStride] = total;
  hreal share = total > 0.0 ? divF(coarse, total) : hreal(0.0);
  // frontierBrdfCount: lround of share x n.
  precise hreal x = min(share, hreal(gFs.maxBrdfShare)) * hreal(n);
  hreal whole = floor(x);
  uint nb = uint(whole) + (subF(x, whole) >= 0.5 ? 1u : 0u);
  gFrHeader.v[kFrontierBrdfCount * gFrStride] = min(nb, n > 0u ? n - 1u : 0u);
}

// The pixel's own table.
void frontierUseOwn() { gFrShared = false; }

// lobeResolved (ht_frontier.cpp).
bool frontierLobeResolved(float r) {
  precise float kr = HT_FRONTIER_LOBE_RADII * r;
  if (ht.material.type == HT_MATERIAL_GGX) return ht.material.alpha >= kr;
  if (ht.material.type == HT_MATERIAL_PHONG) {
    precise float lobeWidth2 = 2.0 / ht.material.exponent;
    precise float nodeWidth2 = 4.0 * kr * kr;
    return lobeWidth2 >= nodeWidth2;
  }
  return true;
}

// frontierProductLevel.
uint frontierProductLevel() {
  uint level = min(gFs.productLevel, ht.order);
  while (level < ht.order && !frontierLobeResolved(scene.htLevelRadius[level])) ++level;
  return level;
}

// frontierLobeFloor at gFrProductLevel.
float frontierLobeFloor() {
  bool resolved = ht.material.type != HT_MATERIAL_LAMBERT && frontierLobeResolved(scene.htLevelRadius[gFrProductLevel]);
  return resolved ? gFs.lobeFloor : gFrBrdfFloor;
}

// Frontier::build's own table: refine from the twelve faces.
void frontierRefine(uint n) {
  frontierUseOwn();
  gFrLobeFloor = frontierLobeFloor();
  gFrOffCand = gFs.offCandidates;
  gFrOffCandMass = gFs.offCandidateMass;
  gFrOffCandKappa = gFs.offCandidateKappa;
  gFrOffHeapKey = gFs.offHeapKey;
  gFrOffHeapIndex = gFs.offHeapIndex;
  gFrCandCount = 0u;
  gFrHeapSize = 0u;
  for (uint f = 0u; f < 12u; ++f) frontierPush(0u, f, 2u, kFrontierNone);
  uint faces = gFrCandCount;
  uint splits = 0u;
  for (; splits < gFrRefinements && gFrHeapSize > 0u; ++splits) {
    uint top = frontierHeapPop();
    GpuFrontierNode nd = gFrCand.v[(top) * gFrPixels];
    uint first = gFrCandCount;
    for (uint j = 0u; j < 4u; ++j) frontierPush(nd.level + 1u, 4u * nd.node + j, nd.visibility & 3u, top);
    gFrCand.v[(top) * gFrPixels].visibility = (nd.visibility & 3u) | 8u | ((gFrCandCount - first) << 4) | (first << 8);
  }
  // The unsplit candidates, depth first: the nested index's order.
  uint count = 0u;
  uint i = 0u;
  bool more = faces > 0u;
  while (more) {
    GpuFrontierNode c = gFrCand.v[(i) * gFrPixels];
    uint children = (c.visibility >> 4) & 7u;
    if ((c.visibility & 8u) != 0u && children > 0u) {
      i = c.visibility >> 8;
      continue;
    }
    if ((c.visibility & 8u) == 0u) {
      gFrNodes.v[(count) * gFrStride] = GpuFrontierNode(c.level, c.node, c.brdfBound, c.brdfCentre, c.visibility & 3u, 0u);
      gFrMass.v[(count) * gFrStride] = gFrCandMass.v[(i) * gFrPixels];
      gFrKappa.v[(count) * gFrStride] = gFrCandKappa.v[(i) * gFrPixels];
      ++count;
    }
    for (;;) {
      uint parent = gFrCand.v[(i) * gFrPixels].link;
      uint end = faces;
      if (parent != kFrontierNone) {
        uint pv = gFrCand.v[(parent) * gFrPixels].visibility;
        end = (pv >> 8) + ((pv >> 4) & 7u);
      }
      if (i + 1u < end) {
        ++i;
        break;
      }
      if (parent == kFrontierNone) {
        more = false;
        break;
      }
      i = parent;
    }
  }
  gFrHeader.v[kFrontierCount * gFrStride] = count;
  gFrHeader.v[kFrontierSplits * gFrStride] = splits;
  gFrHeader.v[kFrontierNodeBase * gFrStride] = 0u;
  gFrHeader.v[kFrontierCumBase * gFrStride] = 0u;
  frontierFinishTable(count, n);
}

// ---------------------------------------------------------------- shared table

void frontierUseShared(uint t) {
  gFrShared = true;
  gFrTable = t;
  gFrNodeBase = tableWord(kFrontierNodeBase);
  gFrCumBase = tableWord(kFrontierCumBase);
}

// The shared table of a flat Lambert point's normal, or kFrontierNone.
uint frontierSharedTable() {
  for (uint t = 0u; t < gFs.sharedCount; ++t)
    if (gFs.sharedNormal[t] == ht.n) return t;
#if !HT_FP64
  // The float shader's HEALPix frame rounds otherwise than the host's.
  for (uint t = 0u; t < gFs.sharedCount; ++t)
    if (dot3(gFs.sharedNormal[t], ht.n) > 0.99999) return t;
#endif
  return kFrontierNone;
}

// A shared table has no mass below the horizon but for nodes the horizon
// cuts: the cap of the point's own plane is left out.
void frontierDropOwnPlane() {
  [[unroll]] for (uint k = 0u; k < kCapSlots; ++k)
    if (dot3(gFrCapAxis[k], ht.n) < -0.9999) gFrCaps &= ~(1u << k);  // an unused slot's bit is clear already
}

// Frontier::build on a shared table: the point's caps (less its own
// plane's) on the faces they reach.
hvec3 frontierApplyCaps(uint table, out hreal colourMass) {
  frontierDropOwnPlane();
  float cR = gFrLevelCos[0], sR = gFrLevelSin[0];
  gFrTouched = 0u;
  hvec3 colourSum = hvec3(0.0);
  colourMass = 0.0;
  for (uint f = 0u; f < 12u; ++f) {
    uint faceCaps = 0u;
    vec3 centre = htCenter(f);
    [[unroll]] for (uint k = 0u; k < kCapSlots; ++k)
      if (((gFrCaps >> k) & 1u) != 0u && dot3(centre, gFrCapAxis[k]) > frontierCosOutside(k, cR, sR))
        faceCaps |= 1u << k;
    if (faceCaps == 0u) {
      uint at = (table * 12u + f) * 4u;
      hvec3 c = hvec3(gFs.sharedFaceColour.v[at], gFs.sharedFaceColour.v[at + 1u], gFs.sharedFaceColour.v[at + 2u]);
      colourSum = frontierAdd3(colourSum, c);
      colourMass = addF(colourMass, gFs.sharedFaceColour.v[at + 3u]);
      continue;
    }
    gFrTouched |= 1u << f;
    hvec3 colour = hvec3(0.0);
    hreal faceMass = 0.0;
    for (uint k = faceStart(f); k < faceStart(f + 1u); ++k) {
      GpuFrontierNode nd = tableNode(k);
      float factor;
      uint cls = frontierNodeClass(nd.level, nd.node, faceCaps, factor);
      hreal mass = tableMass(k);
      hreal pointMass = cls == 1u ? mass : mulF(mass, hreal(factor));
      gFrPointMass.v[(k) * gFrPixels] = pointMass;
      gFrPointClass.v[(k) * gFrPixels] = cls;
      colour = frontierAddColour(colour, pointMass, k, cls, true);
      faceMass = addF(faceMass, pointMass);
    }
    colourSum = frontierAdd3(colourSum, colour);
    colourMass = addF(colourMass, faceMass);
    for (uint bin = 0u; bin < uint(HT_FRONTIER_SEGMENTS) / 12u; ++bin) {
      uint seg = bin * 12u + f;
      hreal acc = 0.0;
      for (uint i = segStart(seg); i < segStart(seg + 1u); ++i) {
        gFrPointCum.v[(i) * gFrPixels] = acc;
        acc = addF(acc, gFrPointMass.v[(tableOrder(i)) * gFrPixels]);
      }
    }
  }
  return colourSum;
}

#endif
