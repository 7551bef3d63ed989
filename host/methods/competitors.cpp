// The talk's other product samplers: wavelet importance sampling (wis,
// wis-biased), two-stage importance sampling (tsis) and resampled
// importance sampling (ris).
#include <algorithm>

#include "healpix.h"
#include "integrator.h"
#include "memory.h"
#include "render.h"
#include "ris.h"
#include "shared.h"
#include "tables.h"
#include "tree.h"
#include "tsis.h"
#include "wis.h"

namespace ht {
const MethodOption kRisCandidates{
    "--ris-candidates", "ris_candidates", "ris, restir*: candidates M per resampled sample (restir*: per chain)", {}, 1,
    4096, [](const MethodOptions& o) { return o.risCandidates; }, [](MethodOptions& o, int v) { o.risCandidates = v; }};

namespace {

static_assert(TsisPoint::kDefaultRegions == HT_TSIS_REGIONS && TsisTable::kMaxLevel == HT_TSIS_MAX_LEVEL);
static_assert(WisPoint::kExactLevels == HT_WIS_EXACT_LEVELS && WisPoint::kMaxOrder == HT_WIS_MAX_ORDER &&
              MaxAvgTree::levelOffset(HT_WIS_EXACT_LEVELS + 1) == HT_WIS_TOP_NODES);
// The largest summed-area table fits one buffer (GpuScene::tsisSat).
static_assert(12ull * ((1ull << HT_TSIS_MAX_LEVEL) + 1) * ((1ull << HT_TSIS_MAX_LEVEL) + 1) * sizeof(double) <=
              (96ull << 20));

// wis's own table: the HEALPix node centres down to its order.
using WisCenters = std::vector<glm::vec3>;

const MethodOption kWisOptions[] = {
    {"--wis-order", "wis_order", "wis*: HEALPix order of the sampled product (Nside 2^order, at most the environment's)",
     {}, 0, WisPoint::kMaxOrder, [](const MethodOptions& o) { return o.wisOrder; },
     [](MethodOptions& o, int v) { o.wisOrder = v; }},
};
const MethodOption kRisOptions[] = {kRisCandidates};

int wisOrder(const RenderSettings& s, int envOrder) {
  return std::clamp(s.options.wisOrder, 0, std::min(envOrder, HT_WIS_MAX_ORDER));
}
uint64_t spp(const RenderSettings& s) { return uint64_t(std::max(s.spp, 1)); }
uint64_t candidates(const RenderSettings& s) { return uint64_t(std::max(s.options.risCandidates, 1)); }

void competitorPush(const RenderSettings& s, gpu::GpuPush& push) {
  push.risCandidates = uint32_t(candidates(s));
  push.wisOrder = uint32_t(std::max(s.options.wisOrder, 0));
}

// wis and wis-biased
void prepareWis(const Scene& scene, Method, const MethodOptions& options, TablesFor, MethodTables& t) {
  t.setOwn(std::make_shared<const WisCenters>(healpixNodeCenters(WisPoint::orderFor(scene.environment, options.wisOrder))));
}
glm::vec3 estimateWisMethod(const Scene& scene, const ShadingPoint& sp, Method method, int spp, Rng&,
                            PixelSampler& sampler, EstimateCounters& counters, const MethodTables& tables,
                            const MethodOptions& options) {
  return estimateWis(scene, sp, spp, options.wisOrder, method == Method::WisBiased, tables.own<WisCenters>(), sampler,
                     counters);
}
void wisMemory(const MemoryInputs& in, MethodMemory& m) {
  const int k = std::clamp(in.options.wisOrder, 0, std::min(in.envOrder, WisPoint::kMaxOrder));
  m.table("wis node centres", MaxAvgTree::levelOffset(k + 1) * 12);
}
// A warped point evaluates the BRDF at every node of the exact levels,
// then four children per level below them; wis-biased averages the
// approximated product over its leaf's pixels.
uint64_t wisLoopCost(const RenderSettings& s, int envOrder, size_t shapes) {
  const int order = wisOrder(s, envOrder);
  uint64_t cost = 12 + 4 * uint64_t(order) + gpuDescentCost(envOrder, shapes);
  if (s.method == Method::WisBiased) cost += uint64_t(1) << (2 * (envOrder - order));
  return cost;
}
uint64_t wisDirections(const RenderSettings& s) {
  return 4 * spp(s) * (HT_WIS_MAX_ORDER - HT_WIS_EXACT_LEVELS) + HT_WIS_TOP_NODES;
}
const GpuSupport kWisGpu{.shader = "competitors", .float64 = true, .loopCost = wisLoopCost,
                         .directionsPerPixel = wisDirections, .push = competitorPush,
                         .makeState = makeCompetitorGpuState};

// tsis
void prepareTsis(const Scene& scene, Method, const MethodOptions&, TablesFor, MethodTables& t) {
  t.setOwn(std::make_shared<const TsisTable>(buildTsisTable(scene.environment)));
}
glm::vec3 estimateTsisMethod(const Scene& scene, const ShadingPoint& sp, Method, int spp, Rng&,
                             PixelSampler& sampler, EstimateCounters& counters, const MethodTables& tables,
                             const MethodOptions&) {
  return estimateTsis(scene, sp, spp, tables.ownPtr<TsisTable>(), sampler, counters);
}
void tsisMemory(const MemoryInputs& in, MethodMemory& m) {
  const uint64_t n = (uint64_t(1) << std::min(in.envOrder, TsisTable::kMaxLevel)) + 1;
  const uint64_t sat = 12 * n * n * 8;
  m.table("tsis summed-area table", sat);
  if (in.gpu) m.gpu += sat;
}
// tsis first partitions the sphere (about five BRDF evaluations per region).
const GpuSupport kTsisGpu{
    .shader = "competitors",
    .float64 = true,
    .loopCost = [](const RenderSettings&, int envOrder, size_t shapes) {
      return 2 * uint64_t(HT_TSIS_REGIONS) + 4 * gpuDescentCost(envOrder, shapes);
    },
    .directionsPerPixel = [](const RenderSettings& s) { return spp(s) + 5 * HT_TSIS_REGIONS; },
    .push = competitorPush,
    .makeState = makeCompetitorGpuState,
};

// ris
glm::vec3 estimateRisMethod(const Scene& scene, const ShadingPoint& sp, Method, int spp, Rng&, PixelSampler& sampler,
                            EstimateCounters& counters, const MethodTables&, const MethodOptions& options) {
  return estimateRis(scene, sp, spp, options.risCandidates, sampler, counters);
}
// M candidates per sample.
const GpuSupport kRisGpu{
    .shader = "competitors",
    .loopCost = [](const RenderSettings& s, int envOrder, size_t shapes) {
      return candidates(s) * gpuDescentCost(envOrder, shapes) + shapes;
    },
    .directionsPerPixel = [](const RenderSettings& s) { return spp(s) * candidates(s); },
    .push = competitorPush,
    .makeState = makeCompetitorGpuState,
};

}  // namespace

using enum Family;
extern const MethodSpec kWis{Method::Wis, "wis",
                             "wavelet importance sampling: warped points on the env x BRDF quadtree, f / p", Competitor,
                             false, false, 1, kWisOptions, prepareWis, estimateWisMethod, wisMemory, &kWisGpu};
extern const MethodSpec kWisBiased{Method::WisBiased, "wis-biased",
                                   "wis returning the approximated product x visibility", Competitor, true, false, 1,
                                   kWisOptions, prepareWis, estimateWisMethod, wisMemory, &kWisGpu};
extern const MethodSpec kTsis{Method::Tsis, "tsis",
                              "two-stage importance sampling: BRDF-driven regions, env SAT inside", Competitor, false,
                              false, 1, {}, prepareTsis, estimateTsisMethod, tsisMemory, &kTsisGpu};
extern const MethodSpec kRis{Method::Ris, "ris",
                             "resampled importance sampling of env x BRDF from env + BRDF candidates", Competitor,
                             false, false, 1, kRisOptions, nullptr, estimateRisMethod, nullptr, &kRisGpu};

}  // namespace ht
