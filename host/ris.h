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
#include "rng.h"
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

  // One candidate from the mixture.
  RisCandidate candidate(Rng& rng) const;
  // M candidates, one kept.
  RisSample sample(int candidates, Rng& rng) const;

  float mixturePdf(const glm::vec3& worldDir) const;
  float target(const glm::vec3& worldDir) const;
  RisCandidate evaluate(const glm::vec3& worldDir, const glm::vec3& radiance, float envPdf) const;

 private:
  const Environment& env_;
  const Material& material_;
  Frame frame_;
  glm::vec3 woLocal_;
};

// The `ris` estimate: `spp` independent resampled samples of M candidates.
glm::vec3 estimateRis(const Scene& scene, const ShadingPoint& sp, int spp, int candidates, Rng& rng,
                      EstimateCounters& counters);

}  // namespace ht
