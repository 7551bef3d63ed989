// The oracle: the brute-force product env x BRDF x visibility, the variance floor.
#include <algorithm>

#include "ht.h"
#include "integrator.h"
#include "memory.h"
#include "oracle.h"
#include "tables.h"
#include "tree.h"

namespace ht {
namespace {

const MethodOption kOracleOptions[] = {
    {"--oracle-order", "oracle_order", "oracle: HEALPix level of the brute-force product", {}, 0, 10,
     [](const MethodOptions& o) { return o.oracleOrder; }, [](MethodOptions& o, int v) { o.oracleOrder = v; }},
};

void prepareOracle(const Scene& scene, Method, const MethodOptions&, TablesFor, MethodTables& t) {
  t.htGeometry = buildHtGeometry(scene.environment.order);
}

glm::vec3 estimate(const Scene& scene, const ShadingPoint& sp, Method, int spp, Rng&, PixelSampler& sampler,
                   EstimateCounters& counters, const MethodTables& tables, const MethodOptions& options) {
  return estimateOracle(scene, sp, spp, options.oracleOrder, tables.geometry(), sampler, counters);
}

void oracleMemory(const MemoryInputs& in, MethodMemory& m) {
  m.table("HT node geometry", MaxAvgTree::levelOffset(in.envOrder + 1) * 20);
  const int k = std::clamp(in.options.oracleOrder, 0, in.envOrder);
  m.table("oracle tables (per thread)", uint64_t(std::max(in.threads, 1)) * MaxAvgTree::levelSize(k) * 40);
}

}  // namespace

extern const MethodSpec kOracle{Method::Oracle, "oracle",
                                "brute-force product env x BRDF x visibility (slow; the variance floor)",
                                Family::Oracle, false, true, 1, kOracleOptions, prepareOracle, estimate,
                                oracleMemory, nullptr};

}  // namespace ht
