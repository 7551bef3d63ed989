// Environment importance sampling by descending the average tree: the face is
// chosen in proportion to its average luminance, then one child in four at
// each level, then a uniform point inside the leaf pixel. One 2-D point
// drives it: u.x picks face and children in nested-index order and, rescaled
// inside each pick, places the point inside the leaf with u.y, so a
// stratified point set stays stratified over the sphere. The density is the
// product of the choice probabilities over the pixel's solid angle, so it is
// proportional to the luminance of L(w).
#pragma once

#include <cstdint>

#include <glm/vec3.hpp>

#include "environment.h"
#include <glm/vec2.hpp>

namespace ht {

struct EnvSample {
  glm::vec3 dir;
  uint64_t pixel;
  float pdf;  // solid-angle density
};

EnvSample sampleEnvironment(const Environment& env, glm::dvec2 u);
float environmentPdf(const Environment& env, const glm::vec3& dir);
// Probability of choosing leaf `pixel` (discrete, sums to 1 over pixels).
double environmentPixelProbability(const Environment& env, uint64_t pixel);

}  // namespace ht
