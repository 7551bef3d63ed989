// Hierarchical thresholding (host/ht.h, host/ht.cpp): the methods ht,
// ht-vis, ht-biased and ht-vis-biased, accepting the same candidates as the
// CPU for the same pixel and seed, in the same order, with the same jitter.
//
// The CPU's recursion becomes a stackless walk (docs/ht.md, "The traversal on the GPU"): the
// state is (level, node, lowest candidate r); going down adds a digit of the
// node's permutation, the next sibling takes the parent's permutation and
// candidate, kept per level of the path (a resumed walk recomputes them
// from the stateless hash). The one value per level the hash cannot give
// back is the smallest bound on the path (leafValue and the biased stop
// clamp to it), kept for data levels only.
//
// The work runs in loops of their own, as a wavefront of one pixel: the
// walk bounds and descends and records the leaves it reaches; a loop values
// them; a loop walks their virtual cells and accepts candidates; a loop
// jitters and shades the accepted samples, in the order accepted. Each
// loop's body is small, which matters where the lanes of a SIMD group run
// every branch of a loop's body (llvmpipe) or wait for each other (GPUs).
//
// Decisions compare the same doubles as the CPU (HT_FP64). They can differ
// where a bound goes through pow, cos, asin or acos (an ulp or two off
// libm's) and lands exactly on the acceptance threshold. HT_FP64 = 0 keeps
// thresholds in float: the same method, no longer the CPU's samples.
#ifndef HT_HT_GLSL
#define HT_HT_GLSL

#include "ht_point.glsl"

// HtPoint::estimateBudget: C_est from the frontier of the nodes with the
// largest bound mass, in the CPU's frontier order.
uint gHtFrontierLevel[HT_MAX_FRONTIER];
uint gHtFrontierNode[HT_MAX_FRONTIER];
hreal gHtFrontierMass[HT_MAX_FRONTIER];
float gHtFrontierEstimate[HT_MAX_FRONTIER];  // HtPoint::nodeEstimate

hreal htEstimateBudget() {
  // A split node stays in place with mass -1 (the order of the others is
  // the CPU's), so no split moves the nodes after it.
  uint size = 0u, live = 0u;
  uint refinements = min((pc.htFlags >> 8) & 0xFFu, uint(HT_MAX_BUDGET_REFINEMENTS));
  uint pushLevel = 0u, pushFirst = 0u, pushCount = 12u;
  for (uint k = 0u;; ++k) {
    for (uint j = 0u; j < pushCount; ++j) {
      HtNode n = htNode(pushLevel, pushFirst + j, true);
      precise hreal mass = hreal(n.bound) * htPixelSolidAngle(pushLevel);
      if (mass > 0.0) {
        precise float floorBound = pc.htBrdfFloor * n.brdfBound;
        float vis = n.visibility == 0u ? 0.0 : n.visibility == 1u ? 1.0 : 0.5;
        precise float estimate = n.envAvg * max(n.brdfValue, floorBound) * vis;
        gHtFrontierLevel[size] = pushLevel;
        gHtFrontierNode[size] = pushFirst + j;
        gHtFrontierMass[size] = mass;
        gHtFrontierEstimate[size] = estimate;
        ++size;
        ++live;
      }
    }
    if (k >= refinements || live == 0u) break;
    uint best = 0u;
    hreal bestMass = gHtFrontierMass[0];
    for (uint i = 1u; i < size; ++i) {
      hreal mass = gHtFrontierMass[i];
      if (bestMass < mass) {
        best = i;
        bestMass = mass;
      }
    }
    uint level = gHtFrontierLevel[best];
    uint node = gHtFrontierNode[best];
    if (level >= ht.order) break;
    gHtFrontierMass[best] = -1.0;
    --live;
    pushLevel = level + 1u;
    pushFirst = 4u * node;
    pushCount = 4u;
  }
  precise hreal c = 0.0;
  for (uint i = 0u; i < size; ++i) {
    if (gHtFrontierMass[i] < 0.0) continue;
    precise hreal term = hreal(gHtFrontierEstimate[i]) * htPixelSolidAngle(gHtFrontierLevel[i]);
    c = c + term;
  }
  return c;
}

// One accepted sample, added to the estimate at once: the CPU sums its
// samples in the order they were accepted, as here.
accvec3 gHtSum = accvec3(0.0);

void htAccept(Shading sh, vec3 dir, uint pixel, float h, uint64_t candidate, uint level, bool averaged,
              vec3 brdfDir, uint sampleIndex) {
  precise hreal inv = 1.0 / (ht.s * hreal(h));
  float weight = float(inv);
  if (pc.htSampleLog != uvec2(0u) && sampleIndex < uint(HT_SAMPLE_LOG_SLOTS)) {
    uint slot = (gl_GlobalInvocationID.y * pc.tileWidth + gl_GlobalInvocationID.x) * uint(HT_SAMPLE_LOG_SLOTS);
    HtSampleLog(pc.htSampleLog).s[slot + sampleIndex] =
        GpuHtSample(dir, h, uvec2(uint(candidate), uint(candidate >> 32)), level, weight);
  }
  vec3 radiance = envRadiance(pixel);
  // Biased samples take the BRDF at the smooth node's centre (HEALPix frame).
  vec3 woLocal = averaged ? ht.woLocal : sh.woLocal;
  vec3 wiLocal = averaged ? toLocal(ht.frame, brdfDir) : toLocal(sh.frame, dir);
  precise vec3 fcos = evalBsdf(sh.material, woLocal, wiLocal);
  if (fcos == vec3(0.0) || radiance == vec3(0.0)) return;
  ++gShadowRays;
  if (occluded(sh.origin, dir)) return;
  precise vec3 product = fcos * radiance;
  precise accvec3 term = accvec3(product) * accvec3(weight);
  precise accvec3 sum = gHtSum + term;
  gHtSum = sum;
}

uint htCompressBits(uint64_t v) {
  v &= 0x5555555555555555ul;
  v = (v | (v >> 1)) & 0x3333333333333333ul;
  v = (v | (v >> 2)) & 0x0F0F0F0F0F0F0F0Ful;
  v = (v | (v >> 4)) & 0x00FF00FF00FF00FFul;
  v = (v | (v >> 8)) & 0x0000FFFF0000FFFFul;
  v = (v | (v >> 16)) & 0x00000000FFFFFFFFul;
  return uint(v);
}


// estimateHt for the ht* methods, in batches: htBegin after estimateDirect's
// draw of the pixel seed, then htSteps until the traversal is done.
//
// The walk bounds the data levels' nodes and descends (HtPoint::visit up
// to the leaf value); the leaves whose lowest candidate passes the path's
// bounds, and the biased stops, it records in order. A loop then gives the
// leaves their values (HtPoint::leafValue), and the cells' loop takes the
// recorded nodes in order: the walk through a leaf's virtual cells
// (HtPoint::visitVirtual) and the acceptance, whose samples wait in the
// pending list for the shading loop. The walk's loop, where lanes diverge
// most, carries no leaf value, cell and acceptance code. One step is a node
// of the walk or of the cells' loop.
struct HtWalk {
  uint seed;
  // The walk over the data levels.
  uint face;
  uint level;
  uint64_t node;
  uint64_t r;  // lowest candidate of the node
  // The recorded leaves and the next to take.
  uint leafCount;
  uint leafNext;
  // The walk through the cells of the leaf taken, while cellActive.
  bool cellActive;
  uint cellLevel;
  uint64_t cellNode;
  uint64_t cellR;
  float leafH;
  // The pending list filled up inside the cell's acceptance: the cell is
  // visited again, its acceptance going on from candidate resumeI.
  bool resume;
  hreal resumeI;
};

// The pixel's pending samples and recorded leaves (HT_QUEUE_BYTES per tile
// pixel): the pixels' pending lists one after the other, then leaf k of
// every pixel side by side, so that the lanes of a SIMD group, which
// record and read their leaves in step, touch neighbouring records.
uint htSlot() { return gl_GlobalInvocationID.y * pc.tileWidth + gl_GlobalInvocationID.x; }
HtPendingList htPendingList() {
  return HtPendingList(uint64_t(pc.htPending) + uint64_t(htSlot()) * uint64_t(HT_PENDING_SLOTS * 64));
}
HtLeafRef htLeaf(uint k) {
  uint64_t pixels = uint64_t(pc.tileWidth * pc.tileHeight);
  return HtLeafRef(uint64_t(pc.htPending) + pixels * uint64_t(HT_PENDING_SLOTS * 64) +
                   (uint64_t(k) * pixels + uint64_t(htSlot())) * 16ul);
}

// The samples accepted and not yet shaded, in the order accepted.
uint gHtPending = 0u;

// Jitters each pending sample in its cell (sample k of the sampler,
// dimension 0), shades it and adds it to the sum, in the order accepted.
void htShadePending(Shading sh, inout Sampler smp) {
  HtPendingList list = htPendingList();
  for (uint k = 0u; k < gHtPending; ++k) {
    GpuHtPending p = list.p[k];
    samplerStart(smp, p.sampleIndex);
    vec2 j = samplerNext2D(smp);
    hreal cells = hreal(p.cells);
    precise hreal dx = (hrealFromBits(p.sx) + hreal(j.x)) / cells;
    precise hreal dy = (hrealFromBits(p.sy) + hreal(j.y)) / cells;
    hvec3 hp = pixToVecAt(p.cellOrder, p.cellPix, dx, dy);
    bool averaged = p.averaged != 0u;
    uint pixel = averaged ? vecToPix(ht.order, hp) : p.cellPix;
    htAccept(sh, fromHealpixFrame(hp), pixel, p.h, p.candidate, p.level, averaged, p.brdfDir, p.sampleIndex);
  }
  gHtPending = 0u;
}
// The smallest bound on the path, per data level (the one value the hash cannot give back).
float gHtPathMin[HT_MAX_ORDER + 1];

// Per level of a walk's path: the node's children's permutation (on data
// levels, with the passing children left above it) and its lowest
// candidate, so that a step to the next sibling or up to the parent
// neither hashes nor divides. The walk over the data levels keeps the
// levels below the map's order, the walk through a leaf's cells the rest.
uint gHtWalkPerm[HT_MAX_WALK_LEVEL];
uint64_t gHtWalkR[HT_MAX_WALK_LEVEL];

// The path's permutations and candidates from the hash, for a walk resumed
// at (level, node) with lowest candidate r: levels `from` to level - 1.
void htRestorePath(uint seed, uint from, uint level, uint64_t node, uint64_t r) {
  for (uint l = from; l < level; ++l) {
    gHtWalkPerm[l] = htPermutation(seed, l, node >> (2u * (level - l)));
    gHtWalkR[l] = r % htStride(l);
  }
}

// Down to the first child of (level, node).
void htDescend(uint seed, inout uint level, inout uint64_t node, inout uint64_t r) {
  uint perm = htPermutation(seed, level, node);
  gHtWalkPerm[level] = perm;
  gHtWalkR[level] = r;
  r += uint64_t(htDigit(perm, 0u)) * htStride(level);
  node *= 4ul;
  ++level;
}

// The next node after (level, node) and everything below it, not going up
// past level `top`: the next sibling, going up over the last children on
// the way (the trailing digits 3 of the nested index), without a loop.
// False when (level, node) was the last below top's node.
bool htNextBelow(uint top, inout uint level, inout uint64_t node, inout uint64_t r) {
  uint lo = ~uint(node), hi = ~uint(node >> 32);
  uint ones = lo != 0u ? uint(findLSB(lo)) : hi != 0u ? 32u + uint(findLSB(hi)) : 64u;
  uint up = min(ones / 2u, level - top);
  if (up > 0u) {
    level -= up;
    node >>= 2u * up;
    r = gHtWalkR[level];
  }
  if (level == top) return false;
  uint j = uint(node & 3ul);
  r = gHtWalkR[level - 1u] + uint64_t(htDigit(gHtWalkPerm[level - 1u], j + 1u)) * htStride(level - 1u);
  ++node;
  return true;
}

// The data walk visits only the children whose lowest candidate passes
// the threshold of their parent's path bound (HtPoint::visit's children
// test: the others accept nothing below), found per family at once, as on
// the CPU: per data level of the path, the passing children not yet
// visited (bits 8 + j of gHtWalkPerm's word, above the permutation), and
// a bit per level that has some left. So a step of the walk is one node,
// with no loop over the failing siblings (a loop's iterations cost every
// lane of a SIMD group the slowest lane's count).
uint gHtWalkLevels = 0u;

// Bit j: child j of the node at `level` with lowest candidate r passes tPath.
uint htPassingChildren(uint perm, uint level, uint64_t r, hreal tPath) {
  uint64_t stride = htStride(level);
  precise hreal r0 = hreal(r + uint64_t(htDigit(perm, 0u)) * stride) + ht.u;
  precise hreal r1 = hreal(r + uint64_t(htDigit(perm, 1u)) * stride) + ht.u;
  precise hreal r2 = hreal(r + uint64_t(htDigit(perm, 2u)) * stride) + ht.u;
  precise hreal r3 = hreal(r + uint64_t(htDigit(perm, 3u)) * stride) + ht.u;
  return (r0 < tPath ? 1u : 0u) | (r1 < tPath ? 2u : 0u) | (r2 < tPath ? 4u : 0u) | (r3 < tPath ? 8u : 0u);
}

// Takes the first of the children left at `level`: child j, and its lowest candidate.
uint htTakeChild(uint level) {
  uint word = gHtWalkPerm[level];
  uint j = uint(findLSB(word >> 8u));
  word &= ~(0x100u << j);
  gHtWalkPerm[level] = word;
  if ((word >> 8u) == 0u) gHtWalkLevels &= ~(1u << level);
  return j;
}

// Down to the first passing child of (level, node), whose path bound gives
// tPath; false when none passes.
bool htDescendPassing(uint seed, hreal tPath, inout uint level, inout uint64_t node, inout uint64_t r) {
  uint perm = htPermutation(seed, level, node);
  uint pass = htPassingChildren(perm, level, r, tPath);
  if (pass == 0u) return false;
  uint j = uint(findLSB(pass));
  pass &= pass - 1u;
  gHtWalkPerm[level] = perm | (pass << 8u);
  gHtWalkR[level] = r;
  if (pass != 0u) gHtWalkLevels |= 1u << level;
  r += uint64_t(htDigit(perm, j)) * htStride(level);
  node = node * 4ul + uint64_t(j);
  ++level;
  return true;
}

// The data walk's next node after (level, node) and everything below it:
// the next passing child of the deepest node on the path with one left;
// after the face's last, the next face (after the last face, face 12).
void htNextPassing(uint64_t faceDigits, inout uint face, inout uint level, inout uint64_t node, inout uint64_t r) {
  uint below = gHtWalkLevels & ((1u << level) - 1u);
  if (below == 0u) {
    ++face;
    level = 0u;
    node = uint64_t(face);
    r = (faceDigits >> (4u * face)) & 15ul;
    return;
  }
  uint p = uint(findMSB(below));
  uint j = htTakeChild(p);
  node = ((node >> (2u * (level - p))) << 2u) | uint64_t(j);
  r = gHtWalkR[p] + uint64_t(htDigit(gHtWalkPerm[p], j)) * htStride(p);
  level = p + 1u;
}

// The children left per level for a data walk resumed at (level, node),
// from the path's permutations, candidates and bounds.
void htRestorePassing(uint level, uint64_t node) {
  gHtWalkLevels = 0u;
  for (uint l = 0u; l < level; ++l) {
    uint child = uint(node >> (2u * (level - l - 1u))) & 3u;
    uint perm = gHtWalkPerm[l] & 0xFFu;
    uint pass = htPassingChildren(perm, l, gHtWalkR[l], htThreshold(gHtPathMin[l]));
    pass &= ~((2u << child) - 1u);
    gHtWalkPerm[l] = perm | (pass << 8u);
    if (pass != 0u) gHtWalkLevels |= 1u << l;
  }
}

// False when the pixel has nothing to sample.
bool htBegin(Shading sh, vec3 position, vec3 normal, vec3 wo, uint spp, inout uint rng, out HtWalk w) {
  w.seed = rngNextUint(rng);
  w.face = 0u;
  w.level = 0u;
  w.node = 0ul;
  w.r = 0ul;
  w.leafCount = 0u;
  w.leafNext = 0u;
  w.cellActive = false;
  w.cellLevel = 0u;
  w.cellNode = 0ul;
  w.cellR = 0ul;
  w.leafH = 0.0;
  w.resume = false;
  w.resumeI = 0.0;
  gHtSum = accvec3(0.0);
  gHtSamples = 0u;
  if (scene.envHasLight == 0u) return false;
  htInit(position, normal, wo, sh.material);
  hreal cEst = htEstimateBudget();
  precise hreal s = hreal(spp) / cEst;
  ht.s = cEst > 0.0 ? s : 0.0;
  ht.u = hreal(rngNext(rng));
  if (ht.s <= 0.0) return false;
  w.r = htFaceDigits(w.seed) & 15ul;
  return true;
}

// HtPoint::leafValue of a recorded leaf (the BRDF bound again: the same
// value as the walk's, in a loop that runs once per leaf, not per node).
float htLeafValue(GpuHtLeaf leaf) {
  uint i = levelOffset(ht.order) + leaf.node;
  uint visibility = (leaf.kind >> 8) & 3u;
  float envAvg = treeAvg(i);
  float brdfBound = htBrdfBound(i);
  if (envAvg <= 0.0 || leaf.h <= 0.0 || brdfBound <= 0.0 || visibility == 0u) return 0.0;
  precise float floorBound = pc.htBrdfFloor * brdfBound;
  precise float h = envAvg * max(htBrdfValue(htCenter(i)), floorBound);
  if (visibility == 2u) h = h * htVisibleFraction(leaf.node);
  return min(h, leaf.h);
}

// The walk over the data levels, up to `steps` steps and until HT_LEAF_SLOTS
// nodes are recorded (w.leafCount, from 0).
void htWalk(inout HtWalk w, uint steps, inout uint step) {
  const bool biased = htBiased();
  const bool visibility = htVisibility();
  const uint64_t faceDigits = htFaceDigits(w.seed);
  uint face = w.face;
  uint level = w.level;
  uint64_t node = w.node;
  uint64_t r = w.r;
  uint count = 0u;
  for (; step < steps && face < 12u && count < uint(HT_LEAF_SLOTS); ++step) {
    ++gHtNodes;
    HtNode n = htNode(level, uint(node), biased);
    float pm = level == 0u ? n.bound : min(gHtPathMin[level - 1u], n.bound);
    gHtPathMin[level] = pm;
    precise hreal ru = hreal(r) + ht.u;
    precise hreal t = htThreshold(n.bound);
    bool descend = false, record = false;
    uint kind = 0u;
    float recordH = 0.0;
    if (!(ru >= t)) {
      bool stopped = false;
      if (biased) {
        // HtPoint::stopEarly: a smooth node holding one acceptable candidate takes it, with the node's average.
        float margin = htBrdfTable() ? HT_BRDF_TABLE_MARGIN : 1.0;
        precise float smoothBound = (1.0 + pc.htBiasedSmoothness) * n.brdfValue * margin;
        precise float twice = 2.0 * n.envAvg;
        precise float product = n.envAvg * n.brdfValue;
        float h = min(pm, product);
        if (n.brdfValue > 0.0 && !(n.brdfBound > smoothBound) && !(n.envMax > twice) &&
            (!visibility || n.visibility == 1u) && h > 0.0) {
          precise hreal th = htThreshold(h);
          precise hreal next = hreal(r) + hreal(htStride(level)) + ht.u;
          stopped = ru >= th || !(next < th);
          if (stopped && !(ru >= th)) {
            record = true;
            kind = level | HT_LEAF_STOP;
            recordH = h;
          }
        }
      }
      if (!stopped && level < ht.order) {
        descend = true;
      } else if (!stopped) {
        record = true;
        kind = level | n.visibility << 8;
        recordH = pm;
      }
    }
    // One store for both kinds: lavapipe stores to a buffer lane by lane, in a loop per word.
    if (record) {
      HtLeafRef slot = htLeaf(count++);  // a local: glslang 11.12 crashes on a store through a call's result
      slot.v = GpuHtLeaf(uint(r), uint(node), recordH, kind);
    }
    bool moved = descend && htDescendPassing(w.seed, htThreshold(pm), level, node, r);
    if (!moved) htNextPassing(faceDigits, face, level, node, r);
  }
  w.face = face;
  w.level = level;
  w.node = node;
  w.r = r;
  w.leafCount = count;
  w.leafNext = 0u;
  // The leaves' values, in a loop of their own: h becomes HtPoint::leafValue.
  for (uint k = 0u; k < count; ++k) {
    HtLeafRef leaf = htLeaf(k);
    if ((leaf.v.kind & HT_LEAF_STOP) == 0u) leaf.v.h = htLeafValue(leaf.v);
  }
}

// The cells' loop: the recorded nodes in order, up to `steps` steps and
// until the pending list is full.
void htCells(inout HtWalk w, uint steps, inout uint step) {
  HtPendingList pending = htPendingList();
  for (; step < steps && (w.cellActive || w.leafNext < w.leafCount) && gHtPending < uint(HT_PENDING_SLOTS); ++step) {
    // The cell's candidates r, r + step, ... below acceptT are accepted in it
    // (cellPix at cellOrder, sub-cell (sx, sy) of a cells x cells grid).
    bool accept = false, averaged = false;
    hreal acceptT = 0.0, acceptStep = 0.0, sx = 0.0, sy = 0.0, cells = 1.0;
    uint level = w.cellLevel, cellOrder = w.cellLevel, cellPix = 0u;
    uint64_t node = w.cellNode, r = w.cellR;
    float sampleH = 0.0;
    vec3 brdfDir = vec3(0.0);
    bool descend = false;
    if (!w.cellActive) {
      GpuHtLeaf leaf = htLeaf(w.leafNext++).v;
      level = leaf.kind & 0xFFu;
      node = uint64_t(leaf.node);
      r = uint64_t(leaf.r);
      if ((leaf.kind & HT_LEAF_STOP) != 0u) {
        // A biased stop: its one candidate, with the node's average.
        accept = averaged = true;
        acceptT = htThreshold(leaf.h);
        acceptStep = hreal(htStride(level));
        cellOrder = level;
        cellPix = leaf.node;
        sampleH = leaf.h;
        brdfDir = htCenter(levelOffset(level) + leaf.node);
      } else {
        w.leafH = leaf.h;
        w.cellActive = w.leafH > 0.0;
        w.resume = false;
      }
    }
    if (w.cellActive) {
      precise hreal t = htThreshold(w.leafH);
      precise hreal ru = hreal(r) + ht.u;
      if (!(ru >= t)) {
        precise hreal stride = hreal(htStride(level));
        precise hreal next = hreal(r) + stride + ht.u;
        if (next < t && level < ht.maxLevel) {
          descend = true;
        } else {
          accept = true;
          acceptT = t;
          acceptStep = stride;
          uint k = level - ht.order;
          uint64_t local = node & ((1ul << (2u * k)) - 1ul);
          cellOrder = ht.order;
          cellPix = uint(node >> (2u * k));
          sx = hreal(htCompressBits(local));
          sy = hreal(htCompressBits(local >> 1));
          cells = hreal(1u << k);
          sampleH = w.leafH;
        }
      }
    }
    bool full = false;
    if (accept) {
      precise hreal i = w.resume ? w.resumeI : hreal(r);
      w.resume = false;
      for (;;) {
        precise hreal iu = i + ht.u;
        if (!(iu < acceptT)) break;
        if (gHtPending == uint(HT_PENDING_SLOTS)) {
          full = true;
          break;
        }
        // Sample k's point inside its cell: sample index k, dimension 0 (htShadePending).
        pending.p[gHtPending] = GpuHtPending(hrealToBits(sx), hrealToBits(sy), uint64_t(i), cellOrder, cellPix,
                                             gHtSamples, level, float(cells), sampleH, averaged ? 1u : 0u, brdfDir);
        ++gHtPending;
        ++gHtSamples;
        i = i + acceptStep;
      }
      if (full) {
        // This cell again once the pending samples are shaded (a stop
        // holds one candidate, so never fills the list).
        w.resume = true;
        w.resumeI = i;
      }
    }
    if (w.cellActive && !full) {
      if (descend) {
        htDescend(w.seed, level, node, r);
      } else {
        w.cellActive = htNextBelow(ht.order, level, node, r);
      }
    }
    w.cellLevel = level;
    w.cellNode = node;
    w.cellR = r;
  }
}

// At most `steps` steps of the traversal; true once it is done. `taken`:
// the steps it took. Whenever the recorded nodes are all taken, the walk
// records more; whenever HT_PENDING_SLOTS samples wait, and at the end, the
// shading loop takes them.
bool htSteps(Shading sh, inout HtWalk w, uint steps, inout Sampler smp, out uint taken) {
  uint step = 0u;
  if (w.cellActive) htRestorePath(w.seed, ht.order, w.cellLevel, w.cellNode, w.cellR);
  if (w.face < 12u) {
    htRestorePath(w.seed, 0u, w.level, w.node, w.r);
    htRestorePassing(w.level, w.node);
  }
  bool finished = w.face == 12u && !w.cellActive && w.leafNext == w.leafCount;
  while (step < steps && !finished) {
    if (!w.cellActive && w.leafNext == w.leafCount) htWalk(w, steps, step);
    htCells(w, steps, step);
    htShadePending(sh, smp);
    finished = w.face == 12u && !w.cellActive && w.leafNext == w.leafCount;
  }
  taken = step;
  return finished;
}

#endif
