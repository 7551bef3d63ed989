// What the rest of the program asks of a sampling method. Each method
// declares it once, as a MethodSpec in its family's file under
// host/methods/, and host/methods/registry.cpp lists the specs: the CLI,
// the stats JSON, the memory estimate, the CPU dispatch, the GPU renderer,
// the bench and the tests iterate them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "common.h"  // shaders/common.h: ht::Method, the methods' numbers
#include "sampler.h"

namespace ht {

namespace gpu {
struct GpuPush;
}
class GpuMethodState;
class PixelSampler;
struct Rng;
struct EstimateCounters;
struct MemoryInputs;
struct MethodTables;
struct RenderResult;
struct RenderSettings;
struct Scene;
struct ShadingPoint;

// The families the methods come from.
enum class Family {
  Baseline,    // one technique per direction (uniform, cosine, env, brdf, mis, mis-compensated)
  Ht,          // the seed's hierarchical thresholding (ht, ht-vis, ht-biased, ht-vis-biased)
  Oracle,      // the brute-force product, the variance floor
  Competitor,  // the talk's other product samplers (wis, tsis, ris)
  Product,     // fixed-count product sampling derived from HT (ht-frontier)
  Reuse,       // spatial reuse between pixels (restir, restir-biased)
};

// Settings of the methods that have any; each field names its method, and
// a MethodOption row in that method's file gives its flag.
struct MethodOptions {
  enum class BrdfBounds { Analytic, Table };
  BrdfBounds brdfBounds = BrdfBounds::Analytic;  // ht*: how the BRDF factor is bounded
  int oracleOrder = 5;                           // oracle: HEALPix level of the brute-force product
  bool htSphereSequence = true;                  // ht*: one sequence over the sphere, or one per face
  int risCandidates = 32;                        // ris: candidates M per resampled sample
  int wisOrder = 5;                              // wis*: HEALPix order of the sampled product (Nside 2^order)
  int frontierRefinements = -1;                  // ht-frontier: most node splits per shading point (< 0: 16 + spp, at most 256)
  bool frontierColourControl = true;             // ht-frontier: the control variate on colour
  int restirNeighbours = 5;                      // restir*: neighbours k per round
  int restirRadius = 30;                         // restir*: neighbours within this many pixels in x and y
  int restirRounds = 2;                          // restir*: rounds r of spatial reuse
  int cutNodes = -1;                             // ht-cut: nodes K of the environment's cut (< 0: by spp, cutNodesFor)
  SamplerKind sampler = SamplerKind::Stratified;  // every method: the per-pixel sample points (sampler.h)
};

// One command-line setting of a method: an integer in [min, max], or with
// `choices` an index into them. `get` and `set` reach its MethodOptions field.
struct MethodOption {
  const char* flag;   // "--wis-order"
  const char* key;    // its name in the stats JSON
  const char* help;
  std::span<const char* const> choices;
  int min = 0, max = 0;
  int (*get)(const MethodOptions&) = nullptr;
  void (*set)(MethodOptions&, int) = nullptr;
};

// A method's part of the render's memory estimate.
struct MethodMemory {
  void table(const char* what, uint64_t bytes);  // a table on the CPU side
  std::vector<std::pair<std::string, uint64_t>> tables;
  uint64_t gpu = 0;  // its buffers on the Vulkan path
};

// What the Vulkan path needs of a method beyond its shader's branch. The
// loop costs and counts are rough: they size dispatches and tiles.
struct GpuSupport {
  const char* shader;     // its family's compute shader: shaders/<shader>.comp.glsl
  bool float64 = false;   // only with shaderFloat64
  bool subgroupVote = false;  // only with subgroupAny in compute shaders
  uint32_t maxTileSide = UINT32_MAX;
  // Loop iterations one sample costs (ht*: one traversal step), for the
  // first batch size; `shapes`: the spheres and planes a ray tests, about.
  uint64_t (*loopCost)(const RenderSettings& s, int envOrder, size_t shapes) = nullptr;
  // Directions a pixel draws, roughly (null: spp).
  uint64_t (*directionsPerPixel)(const RenderSettings& s) = nullptr;
  // Batches run in a tile: (stepsPerSample x spp + fixedSteps) / batch limit.
  uint32_t stepsPerSample = 1, fixedSteps = 0;
  // Its push constants' fields (null: none).
  void (*push)(const RenderSettings& s, gpu::GpuPush& push) = nullptr;
  // The shader's HT_SPEC_BRDF_TABLE (null: off).
  bool (*brdfTable)(const RenderSettings& s) = nullptr;
  // Why it cannot render `scene` ("": it can).
  std::string (*sceneLimit)(Method method, const Scene& scene) = nullptr;
  // Its uploads and scratch (host/gpu_method.h); null: none. Methods with
  // the same factory share one state.
  std::unique_ptr<GpuMethodState> (*makeState)() = nullptr;
  // One tile, the whole image: its pixels read each other's reservoirs.
  bool wholeImage = false;
};

// The loop iterations of one environment sample and its shadow ray, the
// unit GpuSupport::loopCost counts in.
inline uint64_t gpuDescentCost(int envOrder, size_t shapes) { return uint64_t(envOrder) + 4 + shapes; }

using EstimateFn = glm::vec3 (*)(const Scene& scene, const ShadingPoint& sp, Method method, int spp, Rng& rng,
                                 PixelSampler& sampler, EstimateCounters& counters, const MethodTables& tables,
                                 const MethodOptions& options);
enum class TablesFor { Cpu, Gpu };

struct MethodSpec {
  Method method;
  const char* name;
  const char* description;
  Family family;
  bool biased = false;      // converges to something other than the integral
  bool visibility = false;  // the density includes the inner-sphere visibility caps
  int directionsPerSample = 1;
  std::span<const MethodOption> options;
  // The tables it reads at every shading point, built before a render (null: none).
  void (*prepare)(const Scene& scene, Method method, const MethodOptions& options, TablesFor device,
                  MethodTables& tables) = nullptr;
  // Lo at one shading point from `spp` samples (integrator.h: estimateDirect).
  EstimateFn estimate = nullptr;
  // Its tables' and buffers' memory (null: none).
  void (*memory)(const MemoryInputs& in, MethodMemory& out) = nullptr;
  const GpuSupport* gpu = nullptr;  // null: the CPU reference only
  // A method whose pixels read each other's samples renders the image at
  // once (into `out`, sized, background filled) and has no `estimate`.
  void (*renderImage)(const Scene& scene, const RenderSettings& s, RenderResult& out) = nullptr;
};

// Every method, in the order of their numbers.
std::span<const MethodSpec> allMethods();
const MethodSpec& methodSpec(Method m);
std::optional<Method> parseMethod(std::string_view name);
const char* methodName(Method m);
const char* familyName(Family f);
// Every method's options, each flag once, in the methods' order; then --sampler's.
std::span<const MethodOption* const> allMethodOptions();

}  // namespace ht
