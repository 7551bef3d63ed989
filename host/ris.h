// Resampled importance sampling (RIS; Talbot, Cline, Egbert, EGSR 2005),
// the core of ReSTIR DI.
//
// Per sample, M candidates are drawn independently from the one-sample
// mixture p_mix = 0.5 p_env + 0.5 p_brdf (a fair coin picks environment or
// BRDF sampling; the density of a candidate is the mixture's whichever
// strategy drew it). The target is the unshadowed product
// p_hat = luminance(L f cos). One candidate y is kept with probability
// w_i / sum w, w_i = p_hat(x_i) / p_mix(x_i) (a streaming reservoir), and
// only y gets a shadow ray. The estimate
//   L(y) f(y) cos V(y) / p_hat(y) * (1/M) sum w_i
// is unbiased because p_mix > 0 wherever L f cos > 0 and p_hat > 0 wherever
// the shadowed integrand is.
#pragma once

#include <cstdint>

#include <glm/vec3.hpp>

#include "environment.h"
#include "shading.h"
#include "sampler.h"
#include "sampling.h"
#include "scene.h"

namespace ht {

struct RisCandidate {
  glm::vec3 dir{0.0f, 1.0f, 0.0f};  // world space
  glm::vec3 radiance{0.0f};         // L(dir)
  glm::vec3 fcos{0.0f};             // f cos (unshadowed)
  float mixturePdf = 0.0f;          // 0.5 p_env + 0.5 p_brdf
  float target = 0.0f;              // p_hat = luminance(radiance * fcos)
};

struct RisSample {
  RisCandidate chosen;      // target 0 when no candidate had a positive weight
  double weightSum = 0.0;  // sum over the candidates of p_hat / p_mix
  int candidates = 0;
  // Unbiased contribution weight W = weightSum / (M p_hat(y)); 0 if nothing was kept.
  double contributionWeight() const {
    return chosen.target > 0.0f && candidates > 0 ? weightSum / (double(candidates) * chosen.target) : 0.0;
  }
};

class RisSampler {
 public:
  RisSampler(const Environment& env, const Material& m, const glm::vec3& normalWorld, const glm::vec3& woWorld);

  // One candidate from the mixture: u.x below 1/2 takes the environment,
  // else the BRDF; u.x, rescaled to [0,1), and u.y drive the technique.
  RisCandidate candidate(glm::dvec2 u) const;
  // M candidates, one kept, for sample `index` of the pixel. Candidate k's
  // point is dimension 0 of the sampler's sample index M + k, so the
  // candidates of a sample form one stratified set (and those of all
  // samples one larger set). The streaming reservoir keeps candidate k with
  // probability w_k / sum w only if its draws are independent of each other
  // and of the candidates: the draws of candidates 2j and 2j + 1 are the two
  // coordinates of dimension 1 + j of sample `index`, i.i.d.
  RisSample sample(int candidates, PixelSampler& sampler, uint32_t index) const;

  float mixturePdf(const glm::vec3& worldDir) const;
  float target(const glm::vec3& worldDir) const;
  RisCandidate evaluate(const glm::vec3& worldDir, const glm::vec3& radiance, float envPdf) const;

 private:
  const Environment& env_;
  const Material& material_;
  Frame frame_;
  glm::vec3 woLocal_;
};

// The `ris` estimate: `spp` resampled samples of M candidates each.
glm::vec3 estimateRis(const Scene& scene, const ShadingPoint& sp, int spp, int candidates, PixelSampler& sampler,
                      EstimateCounters& counters);

}  // namespace ht
