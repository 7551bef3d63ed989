// One shading point and the integrand every method evaluates there:
// f(wo, wi) cos+(n, wi) V(x, wi) L(wi).
#pragma once

#include <cstdint>

#include <glm/vec3.hpp>

#include "bsdf.h"
#include "sampling.h"
#include "scene.h"

namespace ht {

struct ShadingPoint {
  glm::vec3 position;
  glm::vec3 normal;  // unit, on the side of wo
  glm::vec3 wo;      // unit, towards the viewer
  const Material* material;
  bool flat = false;  // on a plane: points nearby share the normal
};

struct EstimateCounters {
  uint64_t directions = 0;  // directions drawn
  uint64_t shadowRays = 0;
  uint64_t htNodes = 0;     // HT tree nodes visited
};

// The shading frame and ray origin of a point, and the integrand for a
// direction: f cos V L, counting one shadow ray where f cos L is not zero.
// One shadow ray from `origin`, counted: true when nothing blocks wi.
inline bool unoccluded(const Scene& scene, const glm::vec3& origin, const glm::vec3& wi, EstimateCounters& counters) {
  ++counters.shadowRays;
  return !occluded(scene, origin, wi);
}

struct Shading {
  const Scene& scene;
  const Material& material;
  Frame frame;
  glm::vec3 woLocal;
  glm::vec3 origin;
  EstimateCounters& counters;

  Shading(const Scene& sc, const ShadingPoint& sp, EstimateCounters& c)
      : scene(sc),
        material(*sp.material),
        frame(sp.normal),
        woLocal(frame.toLocal(sp.wo)),
        origin(offsetRayOrigin(sp.position, sp.normal)),
        counters(c) {}

  // f cos V for a direction whose radiance is already known.
  glm::vec3 reflected(const glm::vec3& wi, const glm::vec3& radiance) const {
    if (radiance == glm::vec3(0.0f)) return glm::vec3(0.0f);
    glm::vec3 fcos = evalBsdf(material, woLocal, frame.toLocal(wi));
    if (fcos == glm::vec3(0.0f)) return fcos;
    return unoccluded(scene, origin, wi, counters) ? fcos * radiance : glm::vec3(0.0f);
  }
  glm::vec3 reflected(const glm::vec3& wi) const { return reflected(wi, scene.environment.eval(wi)); }
};

}  // namespace ht
