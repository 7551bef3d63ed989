// One shading point of the ht* methods (host/ht.h's HtPoint): its factors
// and their bounds over a node (environment, BRDF, the visibility caps), as
// the CPU computes them (HT_FP64: the same doubles).
#ifndef HT_HT_POINT_GLSL
#define HT_HT_POINT_GLSL

#include "caps.glsl"
#include "ht_table.glsl"
#include "shading.glsl"

#define HT_MAX_FRONTIER (12 + 4 * HT_MAX_BUDGET_REFINEMENTS)

// The 24 permutations of {0, 1, 2, 3} in lexicographic order, digit j in
// bits 2j..2j+1, a byte each, eight to a word, read by shifts: llvmpipe
// rebuilds a constant array indexed per lane at each use, lane by lane.
const uint64_t kHtPermutations[3] = uint64_t[3](0xB1E16C9C78D8B4E4ul, 0x36C672D22D8D39C9ul, 0x1B4B278763931E4Eul);

// Float constants by their bits: the C++ literals round once, GLSL's may round twice.
#define kHtCapMargin uintBitsToFloat(0x3A83126Fu)     // 1e-3f
#define kHtPlaneCapAngle uintBitsToFloat(0x3FC8EF16u) // 0.5f * kPi - 1e-3f
#if HT_FP64
const double kHtFourPi = 12.566370614359172953850573533118lf;
#else
const float kHtFourPi = 12.566370614359172953850573533118;
#endif

// The method's switches: constants where the method is specialized, so
// that the driver drops the code of the variants not run.
bool htVisibility() {
  if (kSpecializedMethod == HT_METHOD_ANY) return (pc.htFlags & HT_FLAG_VISIBILITY) != 0u;
  return kSpecializedMethod == HT_METHOD_HT_VIS || kSpecializedMethod == HT_METHOD_HT_VIS_BIASED;
}
bool htBiased() {
  if (kSpecializedMethod == HT_METHOD_ANY) return (pc.htFlags & HT_FLAG_BIASED) != 0u;
  return kSpecializedMethod == HT_METHOD_HT_BIASED || kSpecializedMethod == HT_METHOD_HT_VIS_BIASED;
}
// HtOptions::brdfTable (kBrdfTable false where it is off).
bool htBrdfTable() { return kBrdfTable && (pc.htFlags & HT_FLAG_BRDF_TABLE) != 0u; }

layout(buffer_reference, scalar, buffer_reference_align = 4) writeonly buffer HtSampleLog { GpuHtSample s[]; };

float htTreeMax(uint i) {
  if (kTexels) return texelFetch(treeMaxTexels, int(i)).x;
  return scene.treeMax[i >> HT_TREE_CHUNK_SHIFT].v[i & ((1u << HT_TREE_CHUNK_SHIFT) - 1u)];
}
vec3 htCenter(uint i) {
  if (kTexels) return texelVec3(htCentersTexels, i);
  return scene.htCenters[i >> HT_HT_VEC3_CHUNK_SHIFT].v[i & ((1u << HT_HT_VEC3_CHUNK_SHIFT) - 1u)];
}
vec2 htCosSinRadius(uint i) {
  if (kTexels) return texelVec2(htConesTexels, i);
  return scene.htCosSinRadius[i >> HT_HT_VEC2_CHUNK_SHIFT].v[i & ((1u << HT_HT_VEC2_CHUNK_SHIFT) - 1u)];
}

// Everything HT needs at one shading point (HtPoint), all in the HEALPix frame.
struct HtPoint {
  GpuMaterial material;
  Frame frame;
  vec3 woLocal, n, wo, mirror;
  float brdfG1;
  uint flags;
  uint order;
  uint maxLevel;
  hreal area;  // measure one candidate sequence covers
  hreal s;     // samples per unit of h
  hreal u;     // the pixel's offset
  HtTableFrame table;  // table bounds
};
HtPoint ht;
vec3 gHtCapAxis[HT_MAX_CAPS];
float gHtCapCos[HT_MAX_CAPS];
// Per cap and data level: the cosines past which a node's cone lies inside
// the cap, or meets it (HtPoint::Cap::cosInside, cosOutside).
float gHtCapCosInside[HT_MAX_CAPS * (HT_MAX_ORDER + 1)];
float gHtCapCosOutside[HT_MAX_CAPS * (HT_MAX_ORDER + 1)];
uint gHtNodes = 0u;
uint gHtSamples = 0u;
uint gHtMaterial = 0u;  // index of the shading point's material (table bounds)


// cos(max(0, angle(a, b) - radius)) and cos(min(pi, angle(a, b) + radius)).
precise float htCosClosest(vec3 a, vec3 b, float cosR, float sinR) {
  precise float c = clamp(dot3(a, b), -1.0, 1.0);
  if (c >= cosR) return 1.0;
  precise float s = sqrt(1.0 - c * c);
  return c * cosR + s * sinR;
}
precise float htCosFarthest(vec3 a, vec3 b, float cosR, float sinR) {
  precise float c = clamp(dot3(a, b), -1.0, 1.0);
  if (c <= -cosR) return -1.0;
  precise float s = sqrt(1.0 - c * c);
  return c * cosR - s * sinR;
}

precise hreal htPixelSolidAngle(uint level) { return kHtFourPi / hreal(12u << (2u * level)); }
precise hreal htThreshold(float h) { return ht.s * hreal(h) * ht.area; }
uint64_t htStride(uint level) {
  return uint64_t((ht.flags & HT_FLAG_SPHERE_SEQUENCE) != 0u ? 12u : 1u) << (2u * level);
}

uint htPermutation(uint seed, uint level, uint64_t node) {
  uint h = pcgHash(seed ^ pcgHash(level ^ pcgHash(uint(node) ^ pcgHash(uint(node >> 32)))));
  uint i = h % 24u;
  uint64_t word = i < 8u ? kHtPermutations[0] : i < 16u ? kHtPermutations[1] : kHtPermutations[2];
  return uint(word >> (8u * (i & 7u))) & 0xFFu;
}
uint htDigit(uint permutation, uint j) { return (permutation >> (2u * j)) & 3u; }

// HtPoint::faceDigit for all faces: 4 bits per face.
uint64_t htFaceDigits(uint seed) {
  uint64_t perm = 0xBA9876543210ul;
  if ((ht.flags & HT_FLAG_SPHERE_SEQUENCE) == 0u) return 0ul;
  uint h = pcgHash(seed ^ 0x9e3779b9u);
  for (uint i = 11u; i > 0u; --i) {
    h = pcgHash(h);
    uint k = h % (i + 1u);
    uint64_t a = (perm >> (4u * i)) & 15ul, b = (perm >> (4u * k)) & 15ul;
    perm &= ~((15ul << (4u * i)) | (15ul << (4u * k)));
    perm |= (b << (4u * i)) | (a << (4u * k));
  }
  return perm;
}

// HtPoint::brdfColour: f cos in colour (no tables).
precise vec3 htBrdfColour(vec3 dirHp) { return evalBsdf(ht.material, ht.woLocal, toLocal(ht.frame, dirHp)); }

precise float htBrdfValue(vec3 dirHp) {
  if (htBrdfTable())
    return htTableAverage(ht.table, vec3(dot3(dirHp, ht.table.x), dot3(dirHp, ht.table.y), dot3(dirHp, ht.n)));
  return luminance(htBrdfColour(dirHp));
}

// HtPoint::brdfBound: each lobe at the smallest angle the node's cone
// allows; `diffuse` receives the diffuse lobe's share.
precise float htBrdfBoundParts(uint i, out float diffuse) {
  vec3 axis = htCenter(i);
  vec2 csr = htCosSinRadius(i);
  float cr = csr.x, sr = csr.y;
  if (htBrdfTable()) {
    diffuse = htTableBound(ht.table, vec3(dot3(axis, ht.table.x), dot3(axis, ht.table.y), dot3(axis, ht.n)), cr, sr);
    return diffuse;
  }
  diffuse = 0.0;
  float cosMax = htCosClosest(axis, ht.n, cr, sr);
  if (cosMax <= 0.0 || ht.woLocal.z <= 0.0) return 0.0;
  precise float b = luminance(ht.material.diffuse) * kInvPi * cosMax;
  diffuse = b;
  if (ht.material.type == HT_MATERIAL_PHONG) {
    float c = htCosClosest(axis, ht.mirror, cr, sr);
    if (c > 0.0) {
      precise float lobe = luminance(ht.material.specular) * (ht.material.exponent + 2.0) * 0.5 * kInvPi *
                           pow(c, ht.material.exponent) * cosMax;
      b = b + lobe;
    }
  } else if (ht.material.type == HT_MATERIAL_GGX) {
    precise float cos2H = 0.5 * (1.0 + htCosClosest(axis, ht.mirror, cr, sr));
    precise float a2 = ht.material.alpha * ht.material.alpha;
    precise float d = cos2H * (a2 - 1.0) + 1.0;
    precise float dMax = a2 / (kPi * d * d);
    precise float cosHalf = sqrt(max(0.0, 0.5 * (1.0 + htCosFarthest(axis, ht.wo, cr, sr))));
    precise float m = 1.0 - cosHalf;
    precise float f0 = luminance(ht.material.specular);
    precise float fresnel = f0 + (1.0 - f0) * m * m * m * m * m;
    precise float lobe = fresnel * dMax * ht.brdfG1 / (4.0 * ht.woLocal.z);
    b = b + lobe;
  }
  return b;
}

precise float htBrdfBound(uint i) {
  float diffuse;
  return htBrdfBoundParts(i, diffuse);
}

// 0: the cone is fully blocked, 1: fully free, 2: partly covered.
uint htVisibilityClass(vec3 axis, uint level) {
  bool partial = false;
  [[unroll]] for (uint k = 0u; k < kCapSlots; ++k) {
    precise float d = dot3(axis, gHtCapAxis[k]);
    uint at = k * uint(HT_MAX_ORDER + 1) + level;
    if (d >= gHtCapCosInside[at]) return 0u;
    if (d > gHtCapCosOutside[at]) partial = true;
  }
  return partial ? 2u : 1u;
}

precise float htVisibleFraction(uint leaf) {
  const vec2 offsets[5] = vec2[5](vec2(0.5, 0.5), vec2(0.25, 0.25), vec2(0.75, 0.25), vec2(0.25, 0.75),
                                  vec2(0.75, 0.75));
  int free = 0;
  for (int o = 0; o < 5; ++o) {
    vec3 d = vec3(pixToVec(ht.order, leaf, offsets[o].x, offsets[o].y));
    bool blocked = false;
    [[unroll]] for (uint k = 0u; k < kCapSlots; ++k) blocked = blocked || dot3(d, gHtCapAxis[k]) > gHtCapCos[k];
    free += blocked ? 0 : 1;
  }
  precise float fraction = float(free) / 5.0;
  return max(pc.htVisibilityFloor, fraction);
}


// A node's factors, each evaluated at one place in the shader (the driver
// inlines every call): the bound (HtPoint::bound), and the BRDF value
// (brdfValue at the centre) where asked for.
struct HtNode {
  uint index;
  vec3 centre;
  float envMax, envAvg;
  float brdfBound;
  float brdfValue;
  uint visibility;  // htVisibilityClass; 1 without visibility
  float bound;
};
HtNode htNode(uint level, uint node, bool withValue) {
  HtNode n;
  n.index = levelOffset(level) + node;
  n.centre = htCenter(n.index);
  n.envMax = htTreeMax(n.index);
  n.envAvg = treeAvg(n.index);
  n.brdfBound = htBrdfBound(n.index);
  n.brdfValue = withValue ? htBrdfValue(n.centre) : 0.0;
  n.visibility = htVisibility() ? htVisibilityClass(n.centre, level) : 1u;
  precise float b = n.envMax * n.brdfBound;
  n.bound = n.envMax <= 0.0 || (b > 0.0 && n.visibility == 0u) ? 0.0 : b;
  return n;
}

// Cap slot k: its axis and half-angle, or none (angle <= 0: a slot no
// direction or node meets).
void htSetCap(uint k, vec3 axis, float angle) {
  bool none = !(angle > 0.0);
  gHtCapAxis[k] = none ? vec3(0.0) : axis;
  gHtCapCos[k] = none ? 2.0 : cos(angle);
  for (uint level = 0u; level <= ht.order; ++level) {
    float rad = scene.htLevelRadius[level];
    precise float inner = angle - rad;
    precise float outer = angle + rad;
    uint at = k * uint(HT_MAX_ORDER + 1) + level;
    gHtCapCosInside[at] = none ? 2.0 : angle > rad ? cos(inner) : 2.0;
    gHtCapCosOutside[at] = none ? 2.0 : cos(min(kPi, outer));
  }
}

// HtPoint's constructor up to the budget.
void htInit(vec3 position, vec3 normal, vec3 wo, GpuMaterial material) {
  ht.material = material;
  ht.flags = pc.htFlags & 0xFFu;
  ht.maxLevel = (pc.htFlags >> 16) & 0xFFu;
  ht.order = scene.envOrder;
  ht.frame = makeFrame(normalize3(vec3(toHealpixFrame(normal))));
  ht.n = ht.frame.n;
  ht.wo = normalize3(vec3(toHealpixFrame(wo)));
  ht.woLocal = toLocal(ht.frame, ht.wo);
  ht.mirror = reflectAbout(ht.wo, ht.n);
  ht.brdfG1 = material.type == HT_MATERIAL_GGX ? ggxG1(ht.woLocal, material.alpha) : 1.0;
  precise hreal face = kHtFourPi / 12.0;
  precise hreal sphere = 12.0 * face;
  ht.area = (ht.flags & HT_FLAG_SPHERE_SEQUENCE) != 0u ? sphere : face;
  if (htBrdfTable()) ht.table = htTableFrame(gHtMaterial, ht.woLocal, ht.wo, ht.n, ht.frame.s);
  if (htVisibility()) {
    // Seen from the shadow rays' origin, as on the CPU.
    precise vec3 origin = offsetRayOrigin(position, normal);
    const uint capped = capSpheres(origin, normal);
    for (uint j = 0u; j < capped; ++j) {
      vec3 axis;
      float sine;
      bool away = sphereCap(j, origin, axis, sine);
      precise float angle = away ? asin(sine) - kHtCapMargin : 0.0;
      htSetCap(j, axis, angle);
    }
    for (uint k = 0u; k < scene.planeCount; ++k) htSetCap(capped + k, planeCapAxis(k, origin), kHtPlaneCapAngle);
    // Slots past the chosen spheres' (fewer than the scene's when some lie below the horizon) block nothing.
    for (uint j = capped + scene.planeCount; j < kCapSlots; ++j) htSetCap(j, vec3(0.0), 0.0);
  }
}

#endif
