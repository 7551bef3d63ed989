// The spheres whose visibility caps a shading point keeps: capSpheres
// (host/scene.cpp) in GLSL, over the BVH of scene.glsl.
#ifndef HT_CAPS_GLSL
#define HT_CAPS_GLSL

#include "environment.glsl"
#include "scene.glsl"

// The selection of each invocation of the workgroup, entry j at
// j * invocations + invocation: in shared memory rather than in 32
// registers, which would raise ht-frontier's peak by as many.
const uint kCapInvocations = HT_WORKGROUP_SIZE * HT_WORKGROUP_SIZE;
shared uint sCapSphere[HT_MAX_CAPS * kCapInvocations];
shared float sCapSine[HT_MAX_CAPS * kCapInvocations];
uint capAt(uint j) { return j * kCapInvocations + gl_LocalInvocationIndex; }
// The j-th sphere capSpheres chose, in increasing index order.
uint capSphere(uint j) { return sCapSphere[capAt(j)]; }

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

// Whether sphere i with `sine` ranks before the j-th entry: a larger sine,
// then a lower index.
bool capBefore(float sine, uint i, uint j) {
  return sine > sCapSine[capAt(j)] || (sine == sCapSine[capAt(j)] && i < sCapSphere[capAt(j)]);
}

// Sphere i into the best `count` of at most k, best first. The loops have
// constant counts, unrolled: llvmpipe allows an invocation 65535 loop
// iterations in all.
void capConsider(uint i, vec3 origin, vec3 normal, uint k, inout uint count) {
  float sine;
  if (!capRank(spheres[i], origin, normal, sine)) return;
  if (count == k && !capBefore(sine, i, k - 1u)) return;
  // Every entry it precedes moves down one place; it takes the first of them.
  uint at = count == k ? k - 1u : count;
  [[unroll]] for (uint j = HT_MAX_CAPS - 1u; j > 0u; --j) {
    if (j <= at && capBefore(sine, i, j - 1u)) {
      sCapSine[capAt(j)] = sCapSine[capAt(j - 1u)];
      sCapSphere[capAt(j)] = sCapSphere[capAt(j - 1u)];
      at = j - 1u;
    }
  }
  sCapSine[capAt(at)] = sine;
  sCapSphere[capAt(at)] = i;
  count = min(count + 1u, k);
}

// capSpheres with `caps` slots (at most HT_MAX_CAPS): the planes' first,
// the spheres' what they leave (capSphereCount).
uint capSpheresIn(vec3 origin, vec3 normal, uint caps) {
  const uint k = caps - min(caps, scene.planeCount);
  if (scene.sphereCount <= k) {
    for (uint i = 0u; i < scene.sphereCount; ++i) sCapSphere[capAt(i)] = i;
    return scene.sphereCount;
  }
  uint count = 0u;
  if (k == 0u) return 0u;
  if (scene.bvhNodeCount == 0u) {
    for (uint i = 0u; i < scene.sphereCount; ++i) capConsider(i, origin, normal, k, count);
  } else {
    // Passes with capSpheres' floors (host/scene.cpp): the first visits the
    // boxes near the point only.
    const float floors[3] = float[3](0.05, 0.01, 0.0);
    for (uint pass = 0u; pass < 3u; ++pass) {
      count = 0u;
      uint node = 0u;
      while (node < scene.bvhNodeCount) {
        GpuBvhNode n = bvhNodes[node];
        const float least = count == k ? max(floors[pass], sCapSine[capAt(k - 1u)]) : floors[pass];
        if (capBound(n, origin) < least) {
          node = n.skip;
          continue;
        }
        if (n.leaf == 0u) {
          ++node;
          continue;
        }
        [[unroll]] for (uint j = 0u; j < uint(HT_BVH_LEAF_SIZE); ++j)
          if (j < (n.leaf & 7u)) capConsider(bvhOrder[(n.leaf >> 3) + j], origin, normal, k, count);
        node = n.skip;
      }
      if (count == k && sCapSine[capAt(k - 1u)] >= floors[pass]) break;
    }
  }
  // In increasing index order, as the CPU keeps them (odd-even transposition sort).
  [[unroll]] for (uint pass = 0u; pass < HT_MAX_CAPS; ++pass)
    [[unroll]] for (uint a = pass & 1u; a + 1u < HT_MAX_CAPS; a += 2u)
      if (a + 1u < count && sCapSphere[capAt(a)] > sCapSphere[capAt(a + 1u)]) {
        uint v = sCapSphere[capAt(a)];
        sCapSphere[capAt(a)] = sCapSphere[capAt(a + 1u)];
        sCapSphere[capAt(a + 1u)] = v;
      }
  return count;
}

uint capSpheres(vec3 origin, vec3 normal) { return capSpheresIn(origin, normal, uint(HT_MAX_CAPS)); }

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
  GpuSphere sp = spheres[capSphere(j)];
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
