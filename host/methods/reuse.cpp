// Spatial reuse between pixels: restir (unbiased, the generalized balance
// heuristic) and restir-biased (1 / sum M), host/restir.h.
#include <algorithm>

#include "memory.h"
#include "render.h"
#include "restir.h"
#include "shared.h"

namespace ht {
namespace {

const MethodOption kRestirOptions[] = {
    kRisCandidates,
    {"--restir-neighbours", "restir_neighbours", "restir*: neighbours k per round of spatial reuse", {}, 0,
     HT_RESTIR_MAX_NEIGHBOURS, [](const MethodOptions& o) { return o.restirNeighbours; },
     [](MethodOptions& o, int v) { o.restirNeighbours = v; }},
    {"--restir-radius", "restir_radius", "restir*: neighbours within this many pixels in x and y", {}, 1, 1024,
     [](const MethodOptions& o) { return o.restirRadius; }, [](MethodOptions& o, int v) { o.restirRadius = v; }},
    {"--restir-rounds", "restir_rounds", "restir*: rounds r of spatial reuse (0: ris)", {}, 0, 8,
     [](const MethodOptions& o) { return o.restirRounds; }, [](MethodOptions& o, int v) { o.restirRounds = v; }},
};

uint64_t candidates(const RenderSettings& s) { return uint64_t(std::max(s.options.risCandidates, 1)); }

void restirMemory(const MemoryInputs& in, MethodMemory& m) {
  const uint64_t pixels = uint64_t(in.width) * uint64_t(in.height);
  // renderRestir's arrays: points, two reservoirs, sampler seeds, sums, counters.
  m.table("restir points and reservoirs", pixels * (sizeof(RestirPoint) + 2 * sizeof(Reservoir) + sizeof(uint32_t) +
                                                    sizeof(glm::dvec3) + sizeof(EstimateCounters)));
  if (in.gpu) m.gpu += pixels * (sizeof(RestirPoint) + 2 * HT_RESTIR_MAX_CHAINS * sizeof(Reservoir));
}

// A pass costs per chain: M candidates (each an environment descent), or
// k + 1 targets and shadow rays.
const GpuSupport kRestirGpu{
    .shader = "restir",
    .loopCost = [](const RenderSettings& s, int envOrder, size_t shapes) {
      const uint64_t k = uint64_t(std::max(s.options.restirNeighbours, 0)) + 1;
      return std::max(candidates(s) * gpuDescentCost(envOrder, shapes) + shapes, k * (2 * shapes + 8));
    },
    .directionsPerPixel = [](const RenderSettings& s) { return uint64_t(std::max(s.spp, 1)) * candidates(s); },
    .stepsPerSample = 4,  // r + 2 passes per group of chains, r = 2 by default
    .push = [](const RenderSettings& s, gpu::GpuPush& push) { push.risCandidates = uint32_t(candidates(s)); },
    .makeState = makeRestirGpuState,
    .wholeImage = true,
};

}  // namespace

using enum Family;
extern const MethodSpec kRestir{Method::Restir, "restir",
                                "ReSTIR spatial reuse of ris reservoirs between pixels, generalized balance heuristic (unbiased)",
                                Reuse, false, false, 1, kRestirOptions, nullptr, nullptr, restirMemory, &kRestirGpu,
                                renderRestir};
extern const MethodSpec kRestirBiased{Method::RestirBiased, "restir-biased",
                                      "restir by 1/sum M with visibility reuse (Bitterli's biased combination)", Reuse, true, false, 1,
                                      kRestirOptions, nullptr, nullptr, restirMemory, &kRestirGpu, renderRestir};

}  // namespace ht
