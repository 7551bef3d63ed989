// The seed's hierarchical thresholding: ht, ht-vis and their biased variants.
#include <algorithm>

#include <fmt/format.h>

#include "brdf_table.h"
#include "error.h"
#include "ht.h"
#include "integrator.h"
#include "memory.h"
#include "render.h"
#include "shared.h"
#include "tables.h"
#include "tree.h"

namespace ht {

HtOptions htOptionsFor(Method method, const MethodOptions& methodOptions) {
  HtOptions options;
  options.visibility = methodSpec(method).visibility;
  options.biased = methodSpec(method).biased;
  options.brdfTable = methodOptions.brdfBounds == MethodOptions::BrdfBounds::Table;
  options.sphereSequence = methodOptions.htSphereSequence;
  return options;
}

std::string gpuCapsLimit(Method method, const Scene& scene) {
  if (methodSpec(method).visibility && scene.planes.size() > HT_MAX_CAPS)
    return fmt::format("method {} on the GPU handles at most {} planes (the scene has {}); use --device cpu",
                       methodName(method), HT_MAX_CAPS, scene.planes.size());
  return {};
}

static_assert(kMaxCaps == HT_MAX_CAPS);

namespace {

constexpr const char* kBoundsChoices[] = {"analytic", "table"};
constexpr const char* kSequenceChoices[] = {"sphere", "faces"};
const MethodOption kHtOptions[] = {
    {"--brdf-bounds", "brdf_bounds", "ht*: BRDF bounds from cones (analytic) or tabulated trees (table)",
     kBoundsChoices, 0, 0, [](const MethodOptions& o) { return int(o.brdfBounds); },
     [](MethodOptions& o, int v) { o.brdfBounds = MethodOptions::BrdfBounds(v); }},
    {"--ht-sequence", "ht_sequence", "ht*: one candidate sequence over the sphere or one per face", kSequenceChoices,
     0, 0, [](const MethodOptions& o) { return o.htSphereSequence ? 0 : 1; },
     [](MethodOptions& o, int v) { o.htSphereSequence = v == 0; }},
};
static_assert(int(MethodOptions::BrdfBounds::Analytic) == 0 && int(MethodOptions::BrdfBounds::Table) == 1);

void prepareHt(const Scene& scene, Method, const MethodOptions& options, TablesFor device, MethodTables& t) {
  t.htGeometry = buildHtGeometry(scene.environment.order);
  if (device == TablesFor::Cpu) t.htNodes = buildHtNodes(*t.htGeometry, scene.environment.tree);
  if (options.brdfBounds == MethodOptions::BrdfBounds::Table) {
    auto tables = std::make_shared<BrdfTables>();
    for (const Material& m : scene.materials) tables->perMaterial.push_back(std::make_shared<const BrdfTable>(m));
    t.setOwn(std::shared_ptr<const BrdfTables>(std::move(tables)));
  }
}

glm::vec3 estimateHtMethod(const Scene& scene, const ShadingPoint& sp, Method method, int spp, Rng& rng,
                           PixelSampler& sampler, EstimateCounters& counters, const MethodTables& tables,
                           const MethodOptions& options) {
  const uint32_t pixelSeed = rng.nextUint();
  return estimateHt(scene, sp, htOptionsFor(method, options), spp, pixelSeed, rng, sampler, counters, tables);
}

void htMemory(const MemoryInputs& in, MethodMemory& m) {
  const uint64_t nodes = MaxAvgTree::levelOffset(in.envOrder + 1);
  m.table("HT node geometry", nodes * 20);
  if (!in.gpu) {
    m.table("HT node records", nodes * 32);
    return;
  }
  // Geometry; per pixel of a tile its pending samples and recorded leaves.
  const uint64_t tile = uint64_t(std::min(in.width, HT_MAX_TILE_SIDE)) * uint64_t(std::min(in.height, HT_MAX_TILE_SIDE));
  m.gpu += nodes * 20 + tile * HT_QUEUE_BYTES;
}

void htPush(const RenderSettings& s, gpu::GpuPush& push) {
  const HtOptions ho = htOptionsFor(s.method, s.options);
  if (ho.budgetRefinements > HT_MAX_BUDGET_REFINEMENTS || ho.maxLevel > HT_MAX_WALK_LEVEL)
    throw Error("internal: HtOptions beyond the shaders' limits");
  push.htFlags = (ho.visibility ? HT_FLAG_VISIBILITY : 0u) | (ho.biased ? HT_FLAG_BIASED : 0u) |
                 (ho.brdfTable ? HT_FLAG_BRDF_TABLE : 0u) | (ho.sphereSequence ? HT_FLAG_SPHERE_SEQUENCE : 0u) |
                 uint32_t(ho.budgetRefinements) << 8 | uint32_t(ho.maxLevel) << 16;
  push.htBrdfFloor = ho.brdfFloor;
  push.htVisibilityFloor = ho.visibilityFloor;
  push.htBiasedSmoothness = ho.biasedSmoothness;
}

const GpuSupport kHtGpu{
    .shader = "ht",
    .maxTileSide = HT_MAX_TILE_SIDE,
    // A step of the walk is one node: its loop, and the caps' (ht-vis);
    // its share of the leaves' visible fractions and of the samples' shading
    // grows with the samples per pixel (measured, ht-vis on spheres.json at
    // 96x48: the longest batch within llvmpipe's loop limit was 4096 steps at
    // 64 spp, 1024 at 256, 512 at 1024).
    .loopCost = [](const RenderSettings& s, int, size_t shapes) {
      const uint64_t caps = std::min<uint64_t>(shapes, HT_MAX_CAPS);
      return (4 + 2 * caps) * std::max<uint64_t>(1, uint64_t(std::max(s.spp, 1)) / 64);
    },
    // The traversal takes some 40 steps per sample, read back to see when it is done.
    .stepsPerSample = 40,
    .fixedSteps = 400,
    .push = htPush,
    .brdfTable = [](const RenderSettings& s) { return htOptionsFor(s.method, s.options).brdfTable; },
    .sceneLimit = gpuCapsLimit,
    .makeState = makeHtGpuState,
};

}  // namespace

using enum Family;
extern const MethodSpec kHt{Method::Ht, "ht", "hierarchical thresholding of env x BRDF", Ht, false, false, 1,
                            kHtOptions, prepareHt, estimateHtMethod, htMemory, &kHtGpu};
extern const MethodSpec kHtVis{Method::HtVis, "ht-vis", "hierarchical thresholding of env x BRDF x visibility", Ht,
                               false, true, 1, kHtOptions, prepareHt, estimateHtMethod, htMemory, &kHtGpu};
extern const MethodSpec kHtBiased{Method::HtBiased, "ht-biased",
                                  "ht with aggressive pruning and averaged BRDF values", Ht, true, false, 1,
                                  kHtOptions, prepareHt, estimateHtMethod, htMemory, &kHtGpu};
extern const MethodSpec kHtVisBiased{Method::HtVisBiased, "ht-vis-biased",
                                     "ht-vis with aggressive pruning and averaged BRDF values", Ht, true, true, 1,
                                     kHtOptions, prepareHt, estimateHtMethod, htMemory, &kHtGpu};

}  // namespace ht
