// ht-cut: exactly n stratified samples of env x BRDF x visibility over a
// fixed cut of HT's tree, every node weighed at every point in one loop,
// the BRDF's samples combined by MIS.
#include <algorithm>

#include "ht.h"
#include "ht_cut.h"
#include "memory.h"
#include "render.h"
#include "shared.h"
#include "tables.h"
#include "tree.h"

namespace ht {

CutOptions cutOptionsFor(const MethodOptions&) { return CutOptions{}; }

namespace {

const MethodOption kCutOptions[] = {
    {"--cut-nodes", "cut_nodes",
     "ht-cut: nodes K of the environment's cut, each weighed at every shading point (-1: 8 x spp within [192, 512])",
     {}, -1, HT_CUT_MAX_NODES, [](const MethodOptions& o) { return o.cutNodes; },
     [](MethodOptions& o, int v) { o.cutNodes = v; }},
};

void prepareCut(const Scene& scene, Method, const MethodOptions& options, TablesFor, MethodTables& t) {
  t.htGeometry = buildHtGeometry(scene.environment.order);
  t.setOwn(std::make_shared<const EnvCut>(buildEnvCut(scene.environment, *t.htGeometry, cutNodesFor(options.cutNodes, 0))));
}

glm::vec3 estimate(const Scene& scene, const ShadingPoint& sp, Method, int spp, Rng& rng, PixelSampler& sampler,
                   EstimateCounters& counters, const MethodTables& tables, const MethodOptions& options) {
  return estimateHtCut(scene, sp, cutOptionsFor(options), spp, rng, sampler, counters, tables.own<EnvCut>(),
                       tables.geometry());
}

void cutMemory(const MemoryInputs& in, MethodMemory& m) {
  const uint64_t nodes = MaxAvgTree::levelOffset(in.envOrder + 1);
  const uint64_t moments = MaxAvgTree::levelOffset(std::min(in.envOrder, kCutMomentLevel) + 1);
  const uint64_t lookup = MaxAvgTree::levelSize(std::min(in.envOrder, kCutMaxLevel));
  m.table("HT node geometry", nodes * 20);
  m.table("ht-cut first moments, chroma and lookup", moments * 24 + lookup * 4);
  // On the device the descent's nodes take three RGBA texels each.
  if (in.gpu) m.gpu += nodes * 20 + moments * 48 + lookup * 4;
}

// Per direction a descent of four children a level down to the product
// level, each under the caps, and the average tree's below it.
const GpuSupport kCutGpu{
    .shader = "cut",
    .subgroupVote = true,
    .loopCost = [](const RenderSettings&, int envOrder, size_t shapes) {
      const uint64_t caps = std::min<uint64_t>(shapes, HT_MAX_CAPS);
      return uint64_t(5) * (4 + 4 * caps) + gpuDescentCost(envOrder, shapes);
    },
    .sceneLimit = gpuCapsLimit,
    .makeState = makeCutGpuState,
};

}  // namespace

extern const MethodSpec kHtCut{
    Method::HtCut, "ht-cut",
    "exactly n stratified samples of env x BRDF x visibility over a fixed cut of HT's tree, BRDF by MIS",
    Family::Product, false, true, 1, kCutOptions, prepareCut, estimate, cutMemory, &kCutGpu};

}  // namespace ht
