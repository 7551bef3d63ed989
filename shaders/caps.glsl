// The spheres whose visibility caps a shading point keeps: capSpheres
// (host/scene.cpp) in GLSL, over the BVH of scene.glsl.
#ifndef HT_CAPS_GLSL
#define HT_CAPS_GLSL

#include "environment.glsl"
#include "scene.glsl"

// The longest selection a shader makes (a shader that keeps fewer defines
// it before this file: the insertion and the sort below take as many
// steps).
#ifndef HT_CAP_LIST
#define HT_CAP_LIST HT_MAX_CAPS
#endif
// The selection of each invocation, entry j: a short one in registers, read
// and written at constant indices only (llvmpipe reads and writes shared
// memory at a per-lane address lane by lane); a long one in shared memory
// at j * invocations + invocation, since 32 registers would raise
// ht-frontier's peak by as many.
#if HT_CAP_LIST <= 8
float gCapSine[HT_CAP_LIST];
uint gCapIndex[HT_CAP_LIST];
#define HT_CAP_SINE(j) gCapSine[j]
#define HT_CAP_INDEX(j) gCapIndex[j]
#else
const uint kCapInvocations = HT_WORKGROUP_SIZE * HT_WORKGROUP_SIZE;
shared uint sCapSphere[HT_CAP_LIST * kCapInvocations];
shared float sCapSine[HT_CAP_LIST * kCapInvocations];
uint capAt(uint j) { return j * kCapInvocations + gl_LocalInvocationIndex; }
#define HT_CAP_SINE(j) sCapSine[capAt(j)]
#define HT_CAP_INDEX(j) sCapSphere[capAt(j)]
#endif

// Entry j where j is not known when compiling (in registers, one select
// per entry): its sine and its sphere (capSphere(j): the j-th sphere
// capSpheres chose, in increasing index order once it is done); capSet
// sets both.
void capEntry(uint j, out float sine, out uint sphere) {
#if HT_CAP_LIST <= 8
  sine = gCapSine[0];
  sphere = gCapIndex[0];
  [[unroll]] for (uint e = 1u; e < HT_CAP_LIST; ++e)
    if (e == j) {
      sine = gCapSine[e];
      sphere = gCapIndex[e];
    }
#else
  sine = sCapSine[capAt(j)];
  sphere = sCapSphere[capAt(j)];
#endif
}
float capSineAt(uint j) {
  float sine;
  uint sphere;
  capEntry(j, sine, sphere);
  return sine;
}
uint capSphere(uint j) {
  float sine;
  uint sphere;
  capEntry(j, sine, sphere);
  return sphere;
}
void capSet(uint j, float sine, uint sphere) {
#if HT_CAP_LIST <= 8
  [[unroll]] for (uint e = 0u; e < HT_CAP_LIST; ++e)
    if (e == j) {
      gCapSine[e] = sine;
      gCapIndex[e] = sphere;
    }
#else
  sCapSine[capAt(j)] = sine;
  sCapSphere[capAt(j)] = sphere;
#endif
}

// capRank: the sine of the sphere's angular radius from `origin`; false at
// the origin or wholly below the plane through it.
bool capRank(GpuSphere s, vec3 origin, vec3 normal, out float sine) {
  precise vec3 d = s.center - origin;
  precise float dist = length3(d);
  sine = 0.0;
  if (!(dist > 0.0) || !(dot3(d, normal) > -s.radius)) return false;
  precise float ratio = s.radius / dist;
  sine = min(1.0, ratio);
  return true;
}

// capBound: no sphere inside the box ranks above it.
float capBound(GpuBvhNode n, vec3 origin) {
  precise vec3 extent = n.hi - n.lo;
  precise float r = 0.5 * min(min(extent.x, extent.y), extent.z);
  precise vec3 gap = max(max(n.lo - origin, origin - n.hi), vec3(0.0));
  precise float dist = length3(gap);
  if (!(dist > 0.0)) return 1.0;
  precise float bound = r / (r + dist) * 1.001 + 1e-6;
  return min(1.0, bound);
}

// Whether sphere i with `sine` ranks before an entry: a larger sine, then a
// lower index.
bool capBefore(float sine, uint i, float entrySine, uint entryIndex) {
  return sine > entrySine || (sine == entrySine && i < entryIndex);
}

// Sphere i into the best `count` of at most k, best first. The loops have
// constant counts, unrolled: llvmpipe allows an invocation 65535 loop
// iterations in all.
void capConsider(uint i, vec3 origin, vec3 normal, uint k, inout uint count) {
  float sine;
  if (!capRank(sphereShape(i), origin, normal, sine)) return;
  if (count == k) {
    float lastSine;
    uint lastSphere;
    capEntry(k - 1u, lastSine, lastSphere);
    if (!capBefore(sine, i, lastSine, lastSphere)) return;
  }
  // Every entry it precedes moves down one place; it takes the first of them.
  uint at = count == k ? k - 1u : count;
  [[unroll]] for (uint j = HT_CAP_LIST - 1u; j > 0u; --j) {
    if (j <= at && capBefore(sine, i, HT_CAP_SINE(j - 1u), HT_CAP_INDEX(j - 1u))) {
      HT_CAP_SINE(j) = HT_CAP_SINE(j - 1u);
      HT_CAP_INDEX(j) = HT_CAP_INDEX(j - 1u);
      at = j - 1u;
    }
  }
  capSet(at, sine, i);
  count = min(count + 1u, k);
}

// capSpheres with `caps` slots (at most HT_CAP_LIST): the planes' first,
// the spheres' what they leave (capSphereCount).
uint capSpheresIn(vec3 origin, vec3 normal, uint caps) {
  const uint k = caps - min(caps, scene.planeCount);
  if (scene.sphereCount <= k) {
    for (uint i = 0u; i < scene.sphereCount; ++i) capSet(i, 0.0, i);
    return scene.sphereCount;
  }
  uint count = 0u;
  if (k == 0u) return 0u;
  if (scene.bvhNodeCount == 0u) {
    for (uint i = 0u; i < scene.sphereCount; ++i) capConsider(i, origin, normal, k, count);
  } else {
    // Passes with capSpheres' floors (host/scene.cpp), each visiting the
    // leaves the passes before left for their floors.
    float above = 2.0;
    for (uint pass = 0u; pass < uint(HT_CAP_PASSES); ++pass) {
      precise float quartered = float(HT_CAP_FIRST_FLOOR) / float(1u << (2u * pass));
      const float floorSine = pass + 1u == uint(HT_CAP_PASSES) ? 0.0 : quartered;
      float least = count == k ? max(floorSine, capSineAt(k - 1u)) : floorSine;
      uint node = 0u;
      while (node < scene.bvhNodeCount) {
        GpuBvhNode n = bvhNode(node);
        const float bound = capBound(n, origin);
        if (bound < least) {
          node = n.skip;
          continue;
        }
        if (n.leaf == 0u) {
          ++node;
          continue;
        }
        if (bound < above) {
          [[unroll]] for (uint j = 0u; j < uint(HT_BVH_LEAF_SIZE); ++j)
            if (j < (n.leaf & 7u)) capConsider(bvhSphere((n.leaf >> 3) + j), origin, normal, k, count);
          if (count == k) least = max(floorSine, capSineAt(k - 1u));
        }
        node = n.skip;
      }
      if (count == k && capSineAt(k - 1u) >= floorSine) break;
      above = floorSine;
    }
  }
  // In increasing index order, as the CPU keeps them (odd-even transposition sort).
  [[unroll]] for (uint pass = 0u; pass < HT_CAP_LIST; ++pass)
    [[unroll]] for (uint a = pass & 1u; a + 1u < HT_CAP_LIST; a += 2u)
      if (a + 1u < count && HT_CAP_INDEX(a) > HT_CAP_INDEX(a + 1u)) {
        uint v = HT_CAP_INDEX(a);
        HT_CAP_INDEX(a) = HT_CAP_INDEX(a + 1u);
        HT_CAP_INDEX(a + 1u) = v;
      }
  return count;
}

uint capSpheres(vec3 origin, vec3 normal) { return capSpheresIn(origin, normal, uint(HT_CAP_LIST)); }

// occluders() (host/ht.cpp), seen from the shadow rays' origin: slot j
// below capSpheres' count the j-th chosen sphere's cap, then one slot per
// plane (its far side); each with its axis in the HEALPix frame and the
// sine of its half-angle. Returns the slots set (a sphere at the origin has
// none). `caps`: as capSpheresIn's.
vec3 gOccluderAxis[HT_MAX_CAPS];
float gOccluderSine[HT_MAX_CAPS];

// The cap of the j-th sphere capSpheres chose, seen from `origin`: its axis
// and the sine of its half-angle; false at the sphere's centre.
bool sphereCap(uint j, vec3 origin, out vec3 axis, out float sine) {
  GpuSphere sp = sphereShape(capSphere(j));
  precise vec3 d = sp.center - origin;
  precise float dist = length3(d);
  precise vec3 unit = d / dist;
  precise float ratio = sp.radius / dist;
  axis = normalize3(vec3(toHealpixFrame(unit)));
  sine = min(1.0, ratio);
  return dist > 0.0;
}

// The axis of plane k's cap (the half-space on its far side) from `origin`.
vec3 planeCapAxis(uint k, vec3 origin) {
  GpuPlane p = planes[k];
  precise vec3 rel = origin - p.point;
  float side = dot3(rel, p.normal);
  vec3 below = side >= 0.0 ? -p.normal : p.normal;
  return normalize3(vec3(toHealpixFrame(below)));
}

uint occluderSlots(vec3 position, vec3 normal, uint caps) {
  uint slots = 0u;
  precise vec3 origin = offsetRayOrigin(position, normal);
  const uint capped = capSpheresIn(origin, normal, caps);
  for (uint j = 0u; j < capped; ++j) {
    if (!sphereCap(j, origin, gOccluderAxis[j], gOccluderSine[j])) continue;
    slots |= 1u << j;
  }
  for (uint k = 0u; k < scene.planeCount; ++k) {
    gOccluderAxis[capped + k] = planeCapAxis(k, origin);
    gOccluderSine[capped + k] = 1.0;
    slots |= 1u << (capped + k);
  }
  return slots;
}

#endif
