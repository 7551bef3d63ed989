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

#include "rng.h"
#include "scene.h"
#include "shading.h"

namespace ht {

enum class Method { Uniform, Cosine, Env, Brdf, Mis, Ht, HtVis, HtBiased, HtVisBiased, Oracle, Wis, WisBiased, Tsis, Ris, HtFrontier };

struct MethodInfo {
  Method method;
  const char* name;
  const char* description;
  bool biased = false;  // converges to something other than the integral
};
std::span<const MethodInfo> allMethods();
std::optional<Method> parseMethod(std::string_view name);
const char* methodName(Method m);

// Settings of the methods that have any; each field names its method.
struct MethodOptions {
  enum class BrdfBounds { Analytic, Table };
  BrdfBounds brdfBounds = BrdfBounds::Analytic;  // ht*: how the BRDF factor is bounded
  int oracleOrder = 5;                           // oracle: HEALPix level of the brute-force product
  bool htSphereSequence = true;                  // ht*: one sequence over the sphere, or one per face
  int risCandidates = 32;                        // ris: candidates M per resampled sample
  int wisOrder = 5;                              // wis*: HEALPix order of the sampled product (Nside 2^order)
  int frontierRefinements = -1;                  // ht-frontier: most node splits per shading point (< 0: 16 + spp, at most 256)
};

// Builds the per-process tables a method uses (HEALPix geometry, BRDF
// tables), so that timing a render does not include them.
void prepareMethod(const Scene& scene, Method method, const MethodOptions& options);

// f(wo, wi) cos+(n, wi) V(x, wi): the integrand without the radiance.
glm::vec3 visibleReflectance(const Scene& scene, const ShadingPoint& sp, const glm::vec3& wi);

// Mean of `spp` independent one-sample estimates (mis: one environment and
// one BRDF direction per sample, power heuristic); for the HT methods, one
// traversal with `spp` expected samples.
glm::vec3 estimateDirect(const Scene& scene, const ShadingPoint& sp, Method method, int spp, Rng& rng,
                         EstimateCounters& counters, const MethodOptions& options = {});

}  // namespace ht
