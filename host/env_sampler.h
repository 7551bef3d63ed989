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

// The same by the average tree `tree` of other values over the map's
// pixels (mis-compensated's): proportional to its leaves, 0 where they are.
EnvSample sampleEnvironment(const Environment& env, const MaxAvgTree& tree, glm::dvec2 u);
float environmentPdf(const Environment& env, const MaxAvgTree& tree, const glm::vec3& dir);
double environmentPixelProbability(const MaxAvgTree& tree, uint64_t pixel);

// The same below node `node` of `level`: children by the average tree from
// there down (pdf: the leaf's probability inside the node over its solid
// angle; 0 for a black node), and a leaf's probability inside its ancestor
// of `level`.
EnvSample sampleEnvironmentBelow(const Environment& env, const MaxAvgTree& tree, int level, uint64_t node,
                                 glm::dvec2 u);
double environmentPixelProbabilityBelow(const MaxAvgTree& tree, int level, uint64_t pixel);
// Child j of four weights with probability w[j] / sum (prob), u rescaled
// into [0, 1) inside the pick.
int pickRescaled4(const float* w, double& u, float& prob);

// MIS compensation (Karlik et al. 2019): the tree of max(0, L_lum - mean
// L_lum) over the map's pixels, which leaves to BRDF sampling the
// directions no brighter than average.
MaxAvgTree compensatedTree(const Environment& env);

}  // namespace ht
