// The baselines: one technique per direction (uniform, cosine, env, brdf),
// two by MIS (mis) and MIS with the compensated environment density
// (mis-compensated).
#include <algorithm>

#include "env_sampler.h"
#include "integrator.h"
#include "memory.h"
#include "render.h"
#include "sampling.h"
#include "shared.h"
#include "shading.h"
#include "tables.h"
#include "tree.h"

namespace ht {

namespace {

float powerHeuristic(float a, float b) {
  float a2 = a * a, b2 = b * b;
  return a2 / (a2 + b2);
}

glm::vec3 estimateBaseline(const Scene& scene, const ShadingPoint& sp, Method method, int spp, Rng&,
                           PixelSampler& sampler, EstimateCounters& counters, const MethodTables& tables,
                           const MethodOptions&) {
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
        const MaxAvgTree& envTree = method == Method::Mis ? env.tree : tables.own<MaxAvgTree>();
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

const GpuSupport kOneTechniqueGpu{
    .shader = "baselines",
    .loopCost = [](const RenderSettings&, int envOrder, size_t shapes) { return gpuDescentCost(envOrder, shapes); },
};
const GpuSupport kMisGpu{
    .shader = "baselines",
    .loopCost = [](const RenderSettings&, int envOrder, size_t shapes) { return 2 * gpuDescentCost(envOrder, shapes); },
    .directionsPerPixel = [](const RenderSettings& s) { return 2 * uint64_t(std::max(s.spp, 1)); },
};
const GpuSupport kMisCompensatedGpu{
    .shader = "baselines",
    .loopCost = kMisGpu.loopCost,
    .directionsPerPixel = kMisGpu.directionsPerPixel,
    .makeState = makeCompensatedGpuState,
};

void prepareCompensated(const Scene& scene, Method, const MethodOptions&, TablesFor, MethodTables& t) {
  t.setOwn(std::make_shared<const MaxAvgTree>(compensatedTree(scene.environment)));
}

void compensatedMemory(const MemoryInputs& in, MethodMemory& m) {
  const uint64_t nodes = MaxAvgTree::levelOffset(in.envOrder + 1);
  m.table("mis-compensated tree", nodes * 8);
  if (in.gpu) m.gpu += nodes * 4;  // its averages
}

}  // namespace

using enum Family;
extern const MethodSpec kUniform{Method::Uniform, "uniform", "uniform directions on the sphere", Baseline, false,
                                 false, 1, {}, nullptr, estimateBaseline, nullptr, &kOneTechniqueGpu};
extern const MethodSpec kCosine{Method::Cosine, "cosine", "cosine-weighted hemisphere around the normal", Baseline,
                                false, false, 1, {}, nullptr, estimateBaseline, nullptr, &kOneTechniqueGpu};
extern const MethodSpec kEnv{Method::Env, "env", "environment importance from the average tree", Baseline, false,
                             false, 1, {}, nullptr, estimateBaseline, nullptr, &kOneTechniqueGpu};
extern const MethodSpec kBrdf{Method::Brdf, "brdf", "BRDF importance (cosine + Phong lobe or GGX visible normals)",
                              Baseline, false, false, 1, {}, nullptr, estimateBaseline, nullptr, &kOneTechniqueGpu};
extern const MethodSpec kMis{Method::Mis, "mis", "one env and one BRDF direction per sample, power heuristic",
                             Baseline, false, false, 2, {}, nullptr, estimateBaseline, nullptr, &kMisGpu};
extern const MethodSpec kMisCompensated{Method::MisCompensated, "mis-compensated",
                                        "mis with the environment's density from max(0, L - mean L) (MIS compensation)",
                                        Baseline, false, false, 2, {}, prepareCompensated, estimateBaseline,
                                        compensatedMemory, &kMisCompensatedGpu};

}  // namespace ht
