// ht-frontier: exactly n stratified samples of env x BRDF x visibility over
// an adaptive frontier of HT's tree, the BRDF's own samples combined by MIS.
#include <algorithm>

#include "ht.h"
#include "ht_frontier.h"
#include "integrator.h"
#include "memory.h"
#include "render.h"
#include "shared.h"
#include "tables.h"
#include "tree.h"

namespace ht {

FrontierOptions frontierOptionsFor(const MethodOptions& methodOptions) {
  FrontierOptions options;
  options.refinements = methodOptions.frontierRefinements;
  options.colourControl = methodOptions.frontierColourControl;
  return options;
}

namespace {

constexpr const char* kOnOff[] = {"on", "off"};
const MethodOption kFrontierOptions[] = {
    {"--frontier-refinements", "frontier_refinements",
     "ht-frontier: most node splits per shading point (frontier of 12 + 3 x this nodes; -1: 16 + spp, at most 256)",
     {}, -1, 4096, [](const MethodOptions& o) { return o.frontierRefinements; },
     [](MethodOptions& o, int v) { o.frontierRefinements = v; }},
    {"--frontier-colour-control", "frontier_colour_control",
     "ht-frontier: the control variate on colour (each table direction's chroma against its exact mean)", kOnOff, 0,
     0, [](const MethodOptions& o) { return o.frontierColourControl ? 0 : 1; },
     [](MethodOptions& o, int v) { o.frontierColourControl = v == 0; }},
};

void prepareFrontier(const Scene& scene, Method, const MethodOptions&, TablesFor device, MethodTables& t) {
  const Environment& env = scene.environment;
  t.htGeometry = buildHtGeometry(env.order);
  if (device == TablesFor::Cpu) t.htNodes = buildHtNodes(*t.htGeometry, env.tree);
  t.setOwn(std::make_shared<const FrontierColours>(frontierColours(env, *t.htGeometry)));
}

glm::vec3 estimate(const Scene& scene, const ShadingPoint& sp, Method, int spp, Rng& rng, PixelSampler& sampler,
                   EstimateCounters& counters, const MethodTables& tables, const MethodOptions& options) {
  return estimateHtFrontier(scene, sp, frontierOptionsFor(options), spp, rng, sampler, counters, tables);
}

void frontierMemory(const MemoryInputs& in, MethodMemory& m) {
  const uint64_t nodes = MaxAvgTree::levelOffset(in.envOrder + 1);
  m.table("HT node geometry", nodes * 20);
  if (!in.gpu) m.table("HT node records", nodes * 32);
  m.table("ht-frontier shared tables (per thread, at most)",
          uint64_t(std::max(in.threads, 1)) * kFrontierSharedTables * kFrontierSharedTableBytes);
  m.table("ht-frontier colour bins, chroma and centroids (and their sums while built)", nodes * 25);
  // Geometry, colour bins, chroma and centroids; a tile's tables (at most the renderer's scratch budget
  // on a CPU device, whose buffers are host memory; a GPU's larger scratch is its own).
  if (in.gpu) m.gpu += nodes * 27 + (uint64_t(96) << 20);
}

// Per direction a descent of four children a level, each under the caps
// (at most HT_MAX_CAPS), and a few binary searches.
const GpuSupport kFrontierGpu{
    .shader = "frontier",
    .loopCost = [](const RenderSettings&, int envOrder, size_t shapes) {
      const uint64_t caps = std::min<uint64_t>(shapes, HT_MAX_CAPS);
      return uint64_t(envOrder) * (4 + 4 * caps) + 40 + gpuDescentCost(envOrder, shapes);
    },
    .sceneLimit = gpuCapsLimit,
    .makeState = makeFrontierGpuState,
};

}  // namespace

extern const MethodSpec kHtFrontier{
    Method::HtFrontier, "ht-frontier",
    "exactly n stratified samples of env x BRDF x visibility over an adaptive HT frontier, BRDF by MIS",
    Family::Product, false, true, 1, kFrontierOptions, prepareFrontier, estimate, frontierMemory, &kFrontierGpu};

}  // namespace ht
