// Direct illumination from the environment at one shading point:
//   Lo = integral of L(w) f(wo, w) cos+(n, w) V(x, w) dw
// estimated with one of the baseline samplers.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include <glm/vec3.hpp>

#include "ht.h"
#include "ht_frontier.h"
#include "rng.h"
#include "sampler.h"
#include "scene.h"
#include "shading.h"
#include "tables.h"

namespace ht {

enum class Method { Uniform, Cosine, Env, Brdf, Mis, Ht, HtVis, HtBiased, HtVisBiased, Oracle, Wis, WisBiased, Tsis, Ris, HtFrontier,
                    MisCompensated };

// The families the methods come from.
enum class Family {
  Baseline,    // one technique per direction (uniform, cosine, env, brdf, mis, mis-compensated)
  Ht,          // the seed's hierarchical thresholding (ht, ht-vis, ht-biased, ht-vis-biased)
  Oracle,      // the brute-force product, the variance floor
  Competitor,  // the talk's other product samplers (wis, tsis, ris)
  Product,     // fixed-count product sampling derived from HT (ht-frontier)
};

// One row per method: what the CLI, the integrator, the GPU renderer, the
// memory estimate and the tests know of it.
struct MethodInfo {
  Method method;
  const char* name;
  const char* description;
  Family family;
  bool biased = false;       // converges to something other than the integral
  bool visibility = false;   // the density includes the inner-sphere visibility caps
  bool gpu = false;          // the Vulkan path renders it
  bool gpuFloat64 = false;   // there, only with shaderFloat64
  int directionsPerSample = 1;
};
std::span<const MethodInfo> allMethods();
const MethodInfo& methodInfo(Method m);
std::optional<Method> parseMethod(std::string_view name);
const char* methodName(Method m);
const char* familyName(Family f);

// Settings of the methods that have any; each field names its method.
struct MethodOptions {
  enum class BrdfBounds { Analytic, Table };
  BrdfBounds brdfBounds = BrdfBounds::Analytic;  // ht*: how the BRDF factor is bounded
  int oracleOrder = 5;                           // oracle: HEALPix level of the brute-force product
  bool htSphereSequence = true;                  // ht*: one sequence over the sphere, or one per face
  int risCandidates = 32;                        // ris: candidates M per resampled sample
  int wisOrder = 5;                              // wis*: HEALPix order of the sampled product (Nside 2^order)
  int frontierRefinements = -1;                  // ht-frontier: most node splits per shading point (< 0: 16 + spp, at most 256)
  bool frontierColourControl = true;             // ht-frontier: the control variate on colour
  SamplerKind sampler = SamplerKind::Stratified;  // every method: the per-pixel sample points (sampler.h)
};

// The HT traversal's options for one of the `ht*` methods, and
// ht-frontier's: what the CPU reference and the GPU path both run.
HtOptions htOptionsFor(Method method, const MethodOptions& options);
FrontierOptions frontierOptionsFor(const MethodOptions& options);

// The tables `method` reads at every shading point of `scene` (HEALPix
// geometry, BRDF tables, wis's node centres, tsis's summed-area table);
// built before a render so that its time leaves them out. A render on the
// GPU leaves out what only the CPU reads (HT's packed node records).
enum class TablesFor { Cpu, Gpu };
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
