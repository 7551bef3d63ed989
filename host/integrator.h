// Direct illumination from the environment at one shading point:
//   Lo = integral of L(w) f(wo, w) cos+(n, w) V(x, w) dw
// estimated with one of the methods (method.h: their specs).
#pragma once

#include <cstdint>

#include <glm/vec3.hpp>

#include "ht.h"
#include "ht_frontier.h"
#include "method.h"
#include "rng.h"
#include "sampler.h"
#include "scene.h"
#include "shading.h"
#include "tables.h"

namespace ht {

// The HT traversal's options for one of the `ht*` methods, and
// ht-frontier's: what the CPU reference and the GPU path both run
// (host/methods/ht_family.cpp, frontier.cpp).
HtOptions htOptionsFor(Method method, const MethodOptions& options);
FrontierOptions frontierOptionsFor(const MethodOptions& options);

// The tables `method` reads at every shading point of `scene` (its spec's
// prepare); built before a render so that its time leaves them out. A
// render on the GPU leaves out what only the CPU reads (HT's packed node
// records).
MethodTables prepareTables(const Scene& scene, Method method, const MethodOptions& options = {},
                           TablesFor device = TablesFor::Cpu);

// f(wo, wi) cos+(n, wi) V(x, wi): the integrand without the radiance.
glm::vec3 visibleReflectance(const Scene& scene, const ShadingPoint& sp, const glm::vec3& wi);

// Mean of `spp` one-sample estimates (mis: one environment and one BRDF
// direction per sample, power heuristic); for the HT methods, one traversal
// with `spp` expected samples. The pixel's sample points are seeded by the
// first draw from rng. `tables`: prepareTables of the same method and options.
glm::vec3 estimateDirect(const Scene& scene, const ShadingPoint& sp, Method method, int spp, Rng& rng,
                         EstimateCounters& counters, const MethodTables& tables, const MethodOptions& options = {});

}  // namespace ht
