#include "bsdf.h"

#include <algorithm>
#include <cmath>

#include "sampling.h"

namespace ht {
namespace {

glm::vec3 schlickFresnel(const glm::vec3& f0, float cosTheta) {
  float m = 1.0f - std::clamp(cosTheta, 0.0f, 1.0f);
  float m5 = m * m * m * m * m;
  return f0 + (glm::vec3(1.0f) - f0) * m5;
}

glm::vec3 mirror(const glm::vec3& wo) { return {-wo.x, -wo.y, wo.z}; }

}  // namespace

glm::vec3 evalBsdf(const Material& m, const glm::vec3& wo, const glm::vec3& wi) {
  if (wo.z <= 0.0f || wi.z <= 0.0f) return glm::vec3(0.0f);
  glm::vec3 result = diffuseFcos(m, wi.z);
  switch (m.type) {
    case MaterialType::Lambert:
      break;
    case MaterialType::Phong: {
      // Normalised Phong: (n + 2) / (2 pi) cos^n of the angle to the mirror direction.
      float c = glm::dot(mirror(wo), wi);
      if (c > 0.0f)
        result += m.specular * ((m.exponent + 2.0f) * 0.5f * kInvPi * std::pow(c, m.exponent) * wi.z);
      break;
    }
    case MaterialType::Ggx: {
      glm::vec3 h = glm::normalize(wo + wi);
      float d = ggxD(h, m.alpha);
      float g = 1.0f / (1.0f + ggxLambda(wo, m.alpha) + ggxLambda(wi, m.alpha));
      result += schlickFresnel(m.specular, glm::dot(wi, h)) * (d * g / (4.0f * wo.z));
      break;
    }
  }
  return result;
}

float specularLobeProbability(const Material& m) {
  if (m.type == MaterialType::Lambert) return 0.0f;
  float s = luminance(m.specular);
  float d = luminance(m.diffuse);
  if (s <= 0.0f) return 0.0f;
  return s / (s + d);
}

glm::vec3 sampleBsdf(const Material& m, const glm::vec3& wo, glm::vec2 u) {
  // u.x picks the lobe and is rescaled inside the part it falls in, so one
  // stratified 2-D point stays stratified within each lobe.
  const float ps = specularLobeProbability(m);
  const bool diffuse = u.x >= ps;
  const float x = diffuse ? (u.x - ps) / (1.0f - ps) : u.x / ps;
  const glm::vec2 uv(std::min(x, kBelowOneF), u.y);
  if (diffuse) return sampleCosineHemisphere(uv);
  if (m.type == MaterialType::Phong) {
    Frame lobe(mirror(wo));
    return lobe.toWorld(samplePowerCosine(uv, m.exponent));
  }
  glm::vec3 h = sampleGgxVisibleNormal(wo, m.alpha, uv);
  return reflectAbout(wo, h);
}

float bsdfPdf(const Material& m, const glm::vec3& wo, const glm::vec3& wi) {
  float ps = specularLobeProbability(m);
  float pdf = (1.0f - ps) * cosineHemispherePdf(wi.z);
  if (ps > 0.0f) {
    if (m.type == MaterialType::Phong)
      pdf += ps * powerCosinePdf(glm::dot(mirror(wo), wi), m.exponent);
    else
      pdf += ps * ggxReflectionPdf(wo, wi, m.alpha);
  }
  return pdf;
}

}  // namespace ht
