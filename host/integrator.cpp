#include "integrator.h"

#include <fmt/format.h>

#include "error.h"

namespace ht {

MethodTables prepareTables(const Scene& scene, Method method, const MethodOptions& options, TablesFor device) {
  MethodTables t;
  if (const auto prepare = methodSpec(method).prepare) prepare(scene, method, options, device, t);
  return t;
}

glm::vec3 visibleReflectance(const Scene& scene, const ShadingPoint& sp, const glm::vec3& wi) {
  EstimateCounters unused;
  return Shading(scene, sp, unused).reflected(wi, glm::vec3(1.0f));
}

glm::vec3 estimateDirect(const Scene& scene, const ShadingPoint& sp, Method method, int spp, Rng& rng,
                         EstimateCounters& counters, const MethodTables& tables, const MethodOptions& options) {
  const MethodSpec& spec = methodSpec(method);
  if (!spec.estimate)
    throw Error(fmt::format("method {} reuses samples between pixels: it renders whole images only", spec.name));
  PixelSampler sampler(options.sampler, rng.nextUint());
  return spec.estimate(scene, sp, method, spp, rng, sampler, counters, tables, options);
}

}  // namespace ht
