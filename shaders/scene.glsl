// Camera, analytic spheres and planes: host/scene.cpp in GLSL.
#ifndef HT_SCENE_GLSL
#define HT_SCENE_GLSL

#include "bindings.glsl"
#include "math.glsl"

struct Ray {
  vec3 origin;
  vec3 dir;  // unit
};

struct Hit {
  float t;
  vec3 position;
  vec3 normal;  // geometric, unit, facing the incoming ray
  uint material;
  bool planar;  // on a plane
};

// cameraRay with the basis and tan(fov / 2) computed on the host (GpuScene).
Ray cameraRay(float px, float py) {
  precise float aspect = float(pc.width) / float(pc.height);
  precise float sx = (2.0 * px / float(pc.width) - 1.0) * scene.tanHalfFov * aspect;
  precise float sy = (1.0 - 2.0 * py / float(pc.height)) * scene.tanHalfFov;
  Ray r;
  r.origin = scene.camPosition;
  precise vec3 d = scene.camW + sx * scene.camU + sy * scene.camV;
  r.dir = normalize3(d);
  return r;
}

// Ray/sphere with the numerically careful discriminant of Haines et al.
bool hitSphere(GpuSphere s, Ray ray, float tMin, float tMax, out float t) {
  precise vec3 f = ray.origin - s.center;
  precise float b = -dot3(f, ray.dir);
  precise vec3 l = f + b * ray.dir;
  precise float disc = s.radius * s.radius - dot3(l, l);
  t = 0.0;
  if (disc < 0.0) return false;
  precise float c = dot3(f, f) - s.radius * s.radius;
  precise float q = b + copySign(sqrt(disc), b);
  precise float t0 = q != 0.0 ? c / q : 0.0;
  float t1 = q;
  if (t0 > t1) {
    float tmp = t0;
    t0 = t1;
    t1 = tmp;
  }
  if (t0 > tMin && t0 < tMax) {
    t = t0;
    return true;
  }
  if (t1 > tMin && t1 < tMax) {
    t = t1;
    return true;
  }
  return false;
}

bool hitPlane(GpuPlane p, Ray ray, float tMin, float tMax, out float t) {
  precise float denom = dot3(p.normal, ray.dir);
  t = 0.0;
  if (denom == 0.0) return false;
  precise float tt = dot3(p.point - ray.origin, p.normal) / denom;
  if (!(tt > tMin && tt < tMax)) return false;
  t = tt;
  return true;
}

// The slab test of rayBox (host/bvh.cpp): whether the ray enters the box
// before tMax, with the same slack for rounding.
bool rayBox(GpuBvhNode n, vec3 o, vec3 inv, float tMax) {
  precise vec3 ta = (n.lo - o) * inv;
  precise vec3 tb = (n.hi - o) * inv;
  precise float enter = max(0.0, max(max(min(ta.x, tb.x), min(ta.y, tb.y)), min(ta.z, tb.z)));
  precise float exit = min(tMax, min(min(max(ta.x, tb.x), max(ta.y, tb.y)), max(ta.z, tb.z)));
  precise float reach = exit + 1e-5 * (abs(enter) + abs(exit));
  return enter <= reach;
}

// A sphere hit with t in (tMin, tMax) as the linear scan in index order
// finds it, through the BVH where the host uploaded one: with `first`, the
// first found (the walk ends there); else the closest, ties to the lower
// index (host/scene.cpp's closestSphere). Its index, or -1, and its t in
// tMax. The walk only prunes, so any order of the leaves gives the same
// sphere.
int sphereHit(Ray ray, float tMin, inout float tMax, bool first) {
  int best = -1;
  float t;
  if (scene.bvhNodeCount == 0u) {
    for (uint i = 0u; i < scene.sphereCount; ++i)
      if (hitSphere(sphereShape(i), ray, tMin, tMax, t)) {
        tMax = t;
        best = int(i);
        if (first) return best;
      }
    return best;
  }
  const float limit = tMax;
  precise vec3 inv = 1.0 / ray.dir;
  uint node = 0u;
  while (node < scene.bvhNodeCount) {
    GpuBvhNode n = bvhNode(node);
    if (!rayBox(n, ray.origin, inv, tMax)) {
      node = n.skip;
      continue;
    }
    if (n.leaf == 0u) {
      ++node;
      continue;
    }
    for (uint k = n.leaf >> 3; k < (n.leaf >> 3) + (n.leaf & 7u); ++k) {
      const int i = int(bvhSphere(k));
      if (hitSphere(sphereShape(uint(i)), ray, tMin, limit, t) && (t < tMax || (t == tMax && i < best))) {
        tMax = t;
        best = i;
        if (first) return best;
      }
    }
    node = n.skip;
  }
  return best;
}

// Nearest hit with t in (tMin, tMax).
bool intersectScene(Ray ray, float tMin, float tMax, out Hit hit) {
  bool any = false;
  float t;
  hit.t = 0.0;
  hit.position = vec3(0.0);
  hit.normal = vec3(0.0);
  hit.material = 0u;
  hit.planar = false;
  const int sphere = sphereHit(ray, tMin, tMax, false);
  if (sphere >= 0) {
    GpuSphere s = sphereShape(uint(sphere));
    any = true;
    hit.t = tMax;
    precise vec3 p = ray.origin + tMax * ray.dir;
    hit.position = p;
    precise vec3 outward = p - s.center;
    hit.normal = normalize3(outward);
    hit.material = spheres[sphere].material;
    hit.planar = false;
  }
  for (uint i = 0u; i < scene.planeCount; ++i) {
    GpuPlane pl = planes[i];
    if (hitPlane(pl, ray, tMin, tMax, t)) {
      tMax = t;
      any = true;
      hit.t = t;
      precise vec3 p = ray.origin + t * ray.dir;
      hit.position = p;
      hit.normal = pl.normal;
      hit.material = pl.material;
      hit.planar = true;
    }
  }
  if (any && dot3(hit.normal, ray.dir) > 0.0) hit.normal = -hit.normal;
  return any;
}

// True if anything blocks the ray leaving `origin` in direction `dir`.
bool occluded(vec3 origin, vec3 dir) {
  Ray ray;
  ray.origin = origin;
  ray.dir = dir;
  float t = kInfinity;
  if (sphereHit(ray, 0.0, t, true) >= 0) return true;
  for (uint i = 0u; i < scene.planeCount; ++i)
    if (hitPlane(planes[i], ray, 0.0, kInfinity, t)) return true;
  return false;
}

// Origin for rays leaving a surface point, pushed off along the normal.
precise vec3 offsetRayOrigin(vec3 p, vec3 n) {
  precise float scale = 1.0 + max(max(abs(p.x), abs(p.y)), abs(p.z));
  return p + n * (1e-4 * scale);
}

#endif
