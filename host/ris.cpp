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

RisCandidate RisSampler::candidate(Rng& rng) const {
  if (rng.next() < 0.5f) {
    const EnvSample s = sampleEnvironment(env_, rng);
    return evaluate(s.dir, s.pdf > 0.0f ? env_.radiance[s.pixel] : glm::vec3(0.0f), s.pdf);
  }
  const glm::vec3 u = rng.next3();
  const glm::vec3 dir = frame_.toWorld(sampleBsdf(material_, woLocal_, u));
  return evaluate(dir, env_.eval(dir), environmentPdf(env_, dir));
}

RisSample RisSampler::sample(int candidates, Rng& rng) const {
  RisSample s;
  s.candidates = std::max(candidates, 1);
  for (int i = 0; i < s.candidates; ++i) {
    const RisCandidate c = candidate(rng);
    const double w = c.target > 0.0f && c.mixturePdf > 0.0f ? double(c.target) / double(c.mixturePdf) : 0.0;
    const float u = rng.next();  // drawn for every candidate: a fixed number of draws per candidate
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

glm::vec3 estimateRis(const Scene& scene, const ShadingPoint& sp, int spp, int candidates, Rng& rng,
                      EstimateCounters& counters) {
  const Environment& env = scene.environment;
  if (!env.hasLight() || spp <= 0) return glm::vec3(0.0f);
  const RisSampler ris(env, *sp.material, sp.normal, sp.wo);
  const glm::vec3 origin = offsetRayOrigin(sp.position, sp.normal);
  glm::dvec3 sum(0.0);
  for (int i = 0; i < spp; ++i) {
    const RisSample s = ris.sample(candidates, rng);
    counters.directions += uint64_t(s.candidates);
    const double weight = s.contributionWeight();
    if (!(weight > 0.0)) continue;
    ++counters.shadowRays;
    if (!occluded(scene, origin, s.chosen.dir)) sum += glm::dvec3(s.chosen.radiance * s.chosen.fcos) * weight;
  }
  return glm::vec3(sum / double(spp));
}

}  // namespace ht
