// Warps from the unit square to directions, each paired with its density
// (solid-angle measure). Local frames have the normal along +z.
#pragma once

#include <cmath>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace ht {

constexpr float kPi = 3.14159265358979323846f;
constexpr float kInvPi = 1.0f / kPi;
// The largest values below 1: where a rescaled uniform must stay in [0,1).
constexpr float kBelowOneF = 0x1.fffffep-1f;
constexpr double kBelowOneD = 0x1.fffffffffffffp-1;

inline float luminance(const glm::vec3& c) { return 0.2126f * c.r + 0.7152f * c.g + 0.0722f * c.b; }

// Orthonormal basis around a unit normal (Duff et al., JCGT 2017).
struct Frame {
  glm::vec3 s, t, n;

  explicit Frame(const glm::vec3& normal) : n(normal) {
    float sign = std::copysign(1.0f, n.z);
    float a = -1.0f / (sign + n.z);
    float b = n.x * n.y * a;
    s = glm::vec3(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x);
    t = glm::vec3(b, sign + n.y * n.y * a, -n.y);
  }
  glm::vec3 toLocal(const glm::vec3& v) const { return {glm::dot(v, s), glm::dot(v, t), glm::dot(v, n)}; }
  glm::vec3 toWorld(const glm::vec3& v) const { return v.x * s + v.y * t + v.z * n; }
};

inline glm::vec3 sampleUniformSphere(glm::vec2 u) {
  float z = 1.0f - 2.0f * u.x;
  float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  float phi = 2.0f * kPi * u.y;
  return {r * std::cos(phi), r * std::sin(phi), z};
}
inline float uniformSpherePdf() { return 0.25f * kInvPi; }

inline glm::vec3 sampleCosineHemisphere(glm::vec2 u) {
  float r = std::sqrt(u.x);
  float phi = 2.0f * kPi * u.y;
  return {r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.0f, 1.0f - u.x))};
}
inline float cosineHemispherePdf(float cosTheta) { return std::max(0.0f, cosTheta) * kInvPi; }

// Density proportional to cos^n around +z over the whole sphere.
inline glm::vec3 samplePowerCosine(glm::vec2 u, float exponent) {
  float z = std::pow(1.0f - u.x, 1.0f / (exponent + 1.0f));
  float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  float phi = 2.0f * kPi * u.y;
  return {r * std::cos(phi), r * std::sin(phi), z};
}
inline float powerCosinePdf(float cosTheta, float exponent) {
  return cosTheta > 0.0f ? (exponent + 1.0f) * 0.5f * kInvPi * std::pow(cosTheta, exponent) : 0.0f;
}

// GGX (Trowbridge-Reitz), isotropic roughness alpha.
inline float ggxD(const glm::vec3& h, float alpha) {
  if (h.z <= 0.0f) return 0.0f;
  float a2 = alpha * alpha;
  float d = h.z * h.z * (a2 - 1.0f) + 1.0f;
  return a2 / (kPi * d * d);
}
inline float ggxLambda(const glm::vec3& w, float alpha) {
  float z2 = w.z * w.z;
  if (z2 <= 0.0f) return 0.0f;
  float tan2 = std::max(0.0f, 1.0f - z2) / z2;
  return 0.5f * (std::sqrt(1.0f + alpha * alpha * tan2) - 1.0f);
}
inline float ggxG1(const glm::vec3& w, float alpha) { return 1.0f / (1.0f + ggxLambda(w, alpha)); }

// Visible-normal sampling (Heitz, JCGT 2018): a microfacet normal seen from wo.
inline glm::vec3 sampleGgxVisibleNormal(const glm::vec3& wo, float alpha, glm::vec2 u) {
  glm::vec3 vh = glm::normalize(glm::vec3(alpha * wo.x, alpha * wo.y, wo.z));
  float lensq = vh.x * vh.x + vh.y * vh.y;
  glm::vec3 t1 = lensq > 0.0f ? glm::vec3(-vh.y, vh.x, 0.0f) / std::sqrt(lensq) : glm::vec3(1, 0, 0);
  glm::vec3 t2 = glm::cross(vh, t1);
  float r = std::sqrt(u.x);
  float phi = 2.0f * kPi * u.y;
  float p1 = r * std::cos(phi);
  float p2 = r * std::sin(phi);
  float s = 0.5f * (1.0f + vh.z);
  p2 = (1.0f - s) * std::sqrt(std::max(0.0f, 1.0f - p1 * p1)) + s * p2;
  glm::vec3 nh = p1 * t1 + p2 * t2 + std::sqrt(std::max(0.0f, 1.0f - p1 * p1 - p2 * p2)) * vh;
  return glm::normalize(glm::vec3(alpha * nh.x, alpha * nh.y, std::max(1e-7f, nh.z)));
}
// Density of the reflected direction wi when h is drawn by the routine above.
inline float ggxReflectionPdf(const glm::vec3& wo, const glm::vec3& wi, float alpha) {
  if (wo.z <= 0.0f) return 0.0f;
  glm::vec3 hv = wo + wi;
  float len = glm::length(hv);
  if (len == 0.0f) return 0.0f;
  glm::vec3 h = hv / len;
  if (h.z <= 0.0f || glm::dot(wo, h) <= 0.0f) return 0.0f;
  return ggxD(h, alpha) * ggxG1(wo, alpha) / (4.0f * wo.z);
}

inline glm::vec3 reflectAbout(const glm::vec3& w, const glm::vec3& n) { return 2.0f * glm::dot(w, n) * n - w; }

}  // namespace ht
