#include "ris.h"

#include <algorithm>

#include "env_sampler.h"

namespace ht {

RisSampler::RisSampler(const Environment& env, const Material& m, const glm::vec3& normalWorld,
                       const glm::vec3& woWorld)
    : env_(env), material_(m), frame_(normalWorld), woLocal_(frame_.toLocal(woWorld)) {}

RisCandidate RisSampler::evaluate(const glm::vec3& dir, const glm::vec3& radiance, float envPdf) const {
  RisCandidate c;
  c.dir = dir;
  c.radiance = radiance;
  const glm::vec3 local = frame_.toLocal(dir);
  c.fcos = evalBsdf(material_, woLocal_, local);
  c.mixturePdf = 0.5f * envPdf + 0.5f * bsdfPdf(material_, woLocal_, local);
  c.target = luminance(radiance * c.fcos);
  return c;
}

RisCandidate RisSampler::candidate(glm::dvec2 u) const {
  if (u.x < 0.5) {
    const EnvSample s = sampleEnvironment(env_, {std::min(2.0 * u.x, kBelowOneD), u.y});
    return evaluate(s.dir, s.pdf > 0.0f ? env_.radiance[s.pixel] : glm::vec3(0.0f), s.pdf);
  }
  const glm::vec2 ub(std::min(float(2.0 * u.x - 1.0), kBelowOneF), float(u.y));
  const glm::vec3 dir = frame_.toWorld(sampleBsdf(material_, woLocal_, ub));
  return evaluate(dir, env_.eval(dir), environmentPdf(env_, dir));
}

RisSample RisSampler::sample(int candidates, PixelSampler& sampler, uint32_t index) const {
  RisSample s;
  s.candidates = std::max(candidates, 1);
  const uint32_t m = uint32_t(s.candidates);
  glm::vec2 draws(0.0f);
  for (uint32_t k = 0; k < m; ++k) {
    sampler.startSample(index * m + k);
    const RisCandidate c = candidate(sampler.get2DPrecise());
    const double w = c.target > 0.0f && c.mixturePdf > 0.0f ? double(c.target) / double(c.mixturePdf) : 0.0;
    if (k % 2 == 0) {
      sampler.startSample(index);
      sampler.setDimension(1 + k / 2);
      draws = sampler.getIndependent2D();
    }
    const float u = k % 2 == 0 ? draws.x : draws.y;
    if (w <= 0.0) continue;
    s.weightSum += w;
    if (double(u) * s.weightSum < w) s.chosen = c;
  }
  return s;
}

float RisSampler::mixturePdf(const glm::vec3& dir) const {
  return 0.5f * environmentPdf(env_, dir) + 0.5f * bsdfPdf(material_, woLocal_, frame_.toLocal(dir));
}

float RisSampler::target(const glm::vec3& dir) const {
  return luminance(env_.eval(dir) * evalBsdf(material_, woLocal_, frame_.toLocal(dir)));
}

glm::vec3 estimateRis(const Scene& scene, const ShadingPoint& sp, int spp, int candidates, PixelSampler& sampler,
                      EstimateCounters& counters) {
  const Environment& env = scene.environment;
  if (!env.hasLight() || spp <= 0) return glm::vec3(0.0f);
  const RisSampler ris(env, *sp.material, sp.normal, sp.wo);
  const glm::vec3 origin = offsetRayOrigin(sp.position, sp.normal);
  glm::dvec3 sum(0.0);
  for (int i = 0; i < spp; ++i) {
    const RisSample s = ris.sample(candidates, sampler, uint32_t(i));
    counters.directions += uint64_t(s.candidates);
    const double weight = s.contributionWeight();
    if (!(weight > 0.0)) continue;
    if (unoccluded(scene, origin, s.chosen.dir, counters)) sum += glm::dvec3(s.chosen.radiance * s.chosen.fcos) * weight;
  }
  return glm::vec3(sum / double(spp));
}

}  // namespace ht
