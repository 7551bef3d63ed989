// Materials: a diffuse lobe plus an optional specular lobe (Phong or GGX).
// All functions work in the local shading frame (normal = +z) and return the
// reflectance times the cosine, f(wo, wi) * max(0, wi.z), in RGB.
#pragma once

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "sampling.h"

namespace ht {

enum class MaterialType { Lambert, Phong, Ggx };

struct Material {
  MaterialType type = MaterialType::Lambert;
  glm::vec3 diffuse{0.5f};  // Lambert albedo (also the optional base of Phong/GGX)
  glm::vec3 specular{0.0f}; // Phong specular colour, GGX F0 / conductor colour
  float exponent = 1.0f;    // Phong exponent
  float alpha = 0.5f;       // GGX roughness
};

// f * cos for a direction pair; zero when either lies below the surface.
glm::vec3 evalBsdf(const Material& m, const glm::vec3& wo, const glm::vec3& wi);
// Its diffuse lobe, the whole of it for Lambert, at cos(wi) = cosI > 0.
inline glm::vec3 diffuseFcos(const Material& m, float cosI) { return m.diffuse * (kInvPi * cosI); }

// Probability of picking the specular lobe when sampling.
float specularLobeProbability(const Material& m);

// Draws wi given wo (u.x chooses the lobe, then drives it with u.y). The result may
// point below the surface, where evalBsdf is zero.
glm::vec3 sampleBsdf(const Material& m, const glm::vec3& wo, glm::vec2 u);
float bsdfPdf(const Material& m, const glm::vec3& wo, const glm::vec3& wi);

}  // namespace ht
