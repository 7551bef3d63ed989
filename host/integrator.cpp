#include "integrator.h"

#include <algorithm>
#include <array>

#include "common.h"  // shaders/common.h: the method numbers

#include "env_sampler.h"
#include "ht.h"
#include "ht_frontier.h"
#include "oracle.h"
#include "ris.h"
#include "tsis.h"
#include "wis.h"
#include "sampling.h"

namespace ht {
namespace {

using enum Family;
constexpr std::array kMethods = {
    MethodInfo{Method::Uniform, "uniform", "uniform directions on the sphere", Baseline, false, false, true},
    MethodInfo{Method::Cosine, "cosine", "cosine-weighted hemisphere around the normal", Baseline, false, false, true},
    MethodInfo{Method::Env, "env", "environment importance from the average tree", Baseline, false, false, true},
    MethodInfo{Method::Brdf, "brdf", "BRDF importance (cosine + Phong lobe or GGX visible normals)", Baseline, false,
               false, true},
    MethodInfo{Method::Mis, "mis", "one env and one BRDF direction per sample, power heuristic", Baseline, false,
               false, true, false, 2},
    MethodInfo{Method::Ht, "ht", "hierarchical thresholding of env x BRDF", Ht, false, false, true},
    MethodInfo{Method::HtVis, "ht-vis", "hierarchical thresholding of env x BRDF x visibility", Ht, false, true, true},
    MethodInfo{Method::HtBiased, "ht-biased", "ht with aggressive pruning and averaged BRDF values", Ht, true, false,
               true},
    MethodInfo{Method::HtVisBiased, "ht-vis-biased", "ht-vis with aggressive pruning and averaged BRDF values", Ht, true,
               true, true},
    MethodInfo{Method::Oracle, "oracle", "brute-force product env x BRDF x visibility (slow; the variance floor)",
               Oracle, false, true},
    MethodInfo{Method::Wis, "wis", "wavelet importance sampling: warped points on the env x BRDF quadtree, f / p",
               Competitor, false, false, true, true},
    MethodInfo{Method::WisBiased, "wis-biased", "wis returning the approximated product x visibility", Competitor, true,
               false, true, true},
    MethodInfo{Method::Tsis, "tsis", "two-stage importance sampling: BRDF-driven regions, env SAT inside", Competitor,
               false, false, true, true},
    MethodInfo{Method::Ris, "ris", "resampled importance sampling of env x BRDF from env + BRDF candidates",
               Competitor, false, false, true},
    MethodInfo{Method::HtFrontier, "ht-frontier",
               "exactly n stratified samples of env x BRDF x visibility over an adaptive HT frontier, BRDF by MIS",
               Product, false, true, true},
    MethodInfo{Method::MisCompensated, "mis-compensated",
               "mis with the environment's density from max(0, L - mean L) (MIS compensation)", Baseline, false, false,
               true, false, 2},
};

constexpr bool registryInEnumOrder() {
  for (size_t i = 0; i < kMethods.size(); ++i)
    if (size_t(kMethods[i].method) != i) return false;
  return true;
}
static_assert(registryInEnumOrder(), "one row per Method, in the enum's order");
// The shaders know the methods by these numbers (shaders/common.h).
static_assert(int(Method::Uniform) == HT_METHOD_UNIFORM && int(Method::Cosine) == HT_METHOD_COSINE &&
              int(Method::Env) == HT_METHOD_ENV && int(Method::Brdf) == HT_METHOD_BRDF &&
              int(Method::Mis) == HT_METHOD_MIS && int(Method::Ht) == HT_METHOD_HT &&
              int(Method::HtVis) == HT_METHOD_HT_VIS && int(Method::HtBiased) == HT_METHOD_HT_BIASED &&
              int(Method::HtVisBiased) == HT_METHOD_HT_VIS_BIASED);
static_assert(int(Method::Oracle) == HT_METHOD_ORACLE && int(Method::Wis) == HT_METHOD_WIS &&
              int(Method::WisBiased) == HT_METHOD_WIS_BIASED && int(Method::Tsis) == HT_METHOD_TSIS &&
              int(Method::Ris) == HT_METHOD_RIS && int(Method::MisCompensated) == HT_METHOD_MIS_COMPENSATED);

float powerHeuristic(float a, float b) {
  float a2 = a * a, b2 = b * b;
  return a2 / (a2 + b2);
}

}  // namespace

std::span<const MethodInfo> allMethods() { return kMethods; }

std::optional<Method> parseMethod(std::string_view name) {
  for (const MethodInfo& m : kMethods)
    if (name == m.name) return m.method;
  return std::nullopt;
}

const MethodInfo& methodInfo(Method m) { return kMethods[size_t(m)]; }

const char* methodName(Method m) { return methodInfo(m).name; }

const char* familyName(Family f) {
  switch (f) {
    case Family::Baseline: return "baseline";
    case Family::Ht: return "ht (seed)";
    case Family::Oracle: return "oracle";
    case Family::Competitor: return "competitor";
    case Family::Product: return "product";
  }
  return "?";
}

HtOptions htOptionsFor(Method method, const MethodOptions& methodOptions) {
  HtOptions options;
  options.visibility = methodInfo(method).visibility;
  options.biased = methodInfo(method).biased;
  options.brdfTable = methodOptions.brdfBounds == MethodOptions::BrdfBounds::Table;
  options.sphereSequence = methodOptions.htSphereSequence;
  return options;
}

FrontierOptions frontierOptionsFor(const MethodOptions& methodOptions) {
  FrontierOptions options;
  options.refinements = methodOptions.frontierRefinements;
  options.colourControl = methodOptions.frontierColourControl;
  return options;
}

MethodTables prepareTables(const Scene& scene, Method method, const MethodOptions& options, TablesFor device) {
  MethodTables t;
  const Environment& env = scene.environment;
  const Family family = methodInfo(method).family;
  if (family == Family::Ht || family == Family::Oracle || method == Method::HtFrontier)
    t.htGeometry = buildHtGeometry(env.order);
  if ((family == Family::Ht || method == Method::HtFrontier) && device == TablesFor::Cpu)
    t.htNodes = buildHtNodes(*t.htGeometry, env.tree);
  if (family == Family::Ht && options.brdfBounds == MethodOptions::BrdfBounds::Table)
    for (const Material& m : scene.materials) t.brdfTables.push_back(std::make_shared<const BrdfTable>(m));
  if (method == Method::Wis || method == Method::WisBiased)
    t.wisCenters = std::make_shared<const std::vector<glm::vec3>>(
        healpixNodeCenters(WisPoint::orderFor(env, options.wisOrder)));
  if (method == Method::Tsis) t.tsis = std::make_shared<const TsisTable>(buildTsisTable(env));
  if (method == Method::HtFrontier)
    t.frontierColours = std::make_shared<const FrontierColours>(frontierColours(env, *t.htGeometry));
  if (method == Method::MisCompensated) t.compensated = std::make_shared<const MaxAvgTree>(compensatedTree(env));
  return t;
}

glm::vec3 visibleReflectance(const Scene& scene, const ShadingPoint& sp, const glm::vec3& wi) {
  EstimateCounters unused;
  return Shading(scene, sp, unused).reflected(wi, glm::vec3(1.0f));
}

glm::vec3 estimateDirect(const Scene& scene, const ShadingPoint& sp, Method method, int spp, Rng& rng,
                         EstimateCounters& counters, const MethodTables& tables, const MethodOptions& methodOptions) {
  PixelSampler sampler(methodOptions.sampler, rng.nextUint());
  if (methodInfo(method).family == Family::Ht) {
    uint32_t pixelSeed = rng.nextUint();
    return estimateHt(scene, sp, htOptionsFor(method, methodOptions), spp, pixelSeed, rng, sampler, counters, tables);
  }
  if (method == Method::Oracle)
    return estimateOracle(scene, sp, spp, methodOptions.oracleOrder, tables.geometry(), sampler, counters);
  if (method == Method::Wis || method == Method::WisBiased)
    return estimateWis(scene, sp, spp, methodOptions.wisOrder, method == Method::WisBiased, tables.wis(), sampler,
                       counters);
  if (method == Method::Tsis) return estimateTsis(scene, sp, spp, tables.tsisTable(), sampler, counters);
  if (method == Method::HtFrontier)
    return estimateHtFrontier(scene, sp, frontierOptionsFor(methodOptions), spp, rng, sampler, counters, tables);
  if (method == Method::Ris) return estimateRis(scene, sp, spp, methodOptions.risCandidates, sampler, counters);
  const Shading sh(scene, sp, counters);
  const Material& mat = *sp.material;
  const Environment& env = scene.environment;
  glm::dvec3 sum(0.0);

  auto bsdfDirection = [&](float& pdf) {
    glm::vec3 local = sampleBsdf(mat, sh.woLocal, sampler.get2D());
    pdf = bsdfPdf(mat, sh.woLocal, local);
    return sh.frame.toWorld(local);
  };

  for (int i = 0; i < spp; ++i) {
    sampler.startSample(uint32_t(i));
    glm::vec3 est(0.0f);
    switch (method) {
      case Method::Uniform: {
        glm::vec3 wi = sampleUniformSphere(sampler.get2D());
        est = sh.reflected(wi) / uniformSpherePdf();
        ++counters.directions;
        break;
      }
      case Method::Cosine: {
        glm::vec3 local = sampleCosineHemisphere(sampler.get2D());
        float pdf = cosineHemispherePdf(local.z);
        if (pdf > 0.0f) est = sh.reflected(sh.frame.toWorld(local)) / pdf;
        ++counters.directions;
        break;
      }
      case Method::Env: {
        EnvSample s = sampleEnvironment(env, sampler.get2DPrecise());
        if (s.pdf > 0.0f) est = sh.reflected(s.dir, env.radiance[s.pixel]) / s.pdf;
        ++counters.directions;
        break;
      }
      case Method::Brdf: {
        float pdf;
        glm::vec3 wi = bsdfDirection(pdf);
        if (pdf > 0.0f) est = sh.reflected(wi) / pdf;
        ++counters.directions;
        break;
      }
      case Method::Mis:
      case Method::MisCompensated: {
        // The environment's technique by its own density; mis-compensated's
        // is zero where L is no brighter than average, and BRDF sampling,
        // positive wherever f cos is, covers those directions alone.
        const MaxAvgTree& envTree = method == Method::Mis ? env.tree : tables.compensatedTree();
        EnvSample s = sampleEnvironment(env, envTree, sampler.get2DPrecise());
        if (s.pdf > 0.0f) {
          float pb = bsdfPdf(mat, sh.woLocal, sh.frame.toLocal(s.dir));
          est += sh.reflected(s.dir, env.radiance[s.pixel]) * (powerHeuristic(s.pdf, pb) / s.pdf);
        }
        float pb;
        glm::vec3 wi = bsdfDirection(pb);
        if (pb > 0.0f) {
          float pe = environmentPdf(env, envTree, wi);
          est += sh.reflected(wi) * (powerHeuristic(pb, pe) / pb);
        }
        counters.directions += 2;
        break;
      }
      default:
        break;
    }
    sum += glm::dvec3(est);
  }
  return glm::vec3(sum / double(std::max(spp, 1)));
}

}  // namespace ht
