// Wavelet importance sampling (WIS; Clarberg, Jarosz, Akenine-Moller,
// Jensen, SIGGRAPH 2005) on the HEALPix hierarchy.
//
// The HEALPix quadtree of each base face is the Haar hierarchy of the
// environment: a node's average is its scaling coefficient, and the four
// children differ from it by the three Haar details. The product of the
// environment and the BRDF slice for the current wo is represented on that
// hierarchy, truncated at the WIS order (a coarser map than the renderer's
// environment), and sampled by hierarchical sample warping: a stratified
// point set is split at every node first in x, then in y, in proportion to
// the children's weights, so that each point ends in a leaf with the
// probability of that leaf and keeps a uniform position inside it.
//
// Node weights (docs/competitors.md, "wis"):
//   level l <= kExactLevels:   sums of the piecewise-constant product at
//                              level kExactLevels, i.e. the exact average
//                              tree of that product;
//   deeper nodes:              env average (luminance) x BRDF luminance at
//                              the node centre, plus a small floor,
// evaluated lazily where the warping goes. The probability of a leaf is the
// product of the branch probabilities along its path, so the density is
// exact for every direction and f / p is unbiased. `wis-biased` instead
// returns the approximated product of the leaf (env average x BRDF at its
// centre) times the shadow ray.
#pragma once

#include <array>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "environment.h"
#include "shading.h"
#include "sampler.h"
#include "sampling.h"
#include "scene.h"

namespace ht {

// Splits u in [0,1) at p: returns true (first part) for u < p and rescales u
// to [0,1) inside the part taken.
bool splitUnit(double& u, double p);

// Luminance of f cos for directions given in the HEALPix frame.
struct HealpixFrameBrdf {
  HealpixFrameBrdf(const Environment& env, const Material& m, const glm::vec3& normalWorld, const glm::vec3& woWorld);
  glm::vec3 rgb(const glm::vec3& dirHp) const { return evalBsdf(material, woLocal, frame.toLocal(dirHp)); }
  float value(const glm::vec3& dirHp) const { return luminance(rgb(dirHp)); }
  // Scale of the BRDF (diffuse + specular luminance over pi): the floors
  // that keep every lit direction samplable are fractions of it.
  float scale() const;

  const Material& material;
  Frame frame;        // shading frame, HEALPix frame
  glm::vec3 woLocal;  // in the shading frame
  glm::vec3 n, wo;    // HEALPix frame
};

// Node centres (HEALPix frame) of every level up to `order`, flat per-level
// layout of MaxAvgTree.
std::vector<glm::vec3> healpixNodeCenters(int order);

struct WisSample {
  glm::vec3 dir;       // world space
  uint64_t pixel;      // leaf of the WIS tree (nested index at the WIS order)
  double probability;  // of choosing that leaf
  double pdf;          // solid-angle density
};

class WisPoint {
 public:
  static constexpr int kExactLevels = 3;       // product summed exactly up from this level
  static constexpr int kMaxOrder = 9;          // the WIS order is clamped to this and to the map's order
  static constexpr float kBrdfFloor = 1e-3f;   // BRDF weight >= this x HealpixFrameBrdf::scale()

  // `centers`: healpixNodeCenters of orderFor(env, order) or deeper.
  WisPoint(const Environment& env, const Material& m, const glm::vec3& normalWorld, const glm::vec3& woWorld,
           int order, const std::vector<glm::vec3>& centers);
  // The order a point uses for a requested one.
  static int orderFor(const Environment& env, int order);

  // The order actually used: min(requested, map order, kMaxOrder), >= 0 (orderFor).
  int order() const { return order_; }
  // True when no direction can be sampled (black map or black material).
  bool empty() const { return !(total_ > 0.0); }

  // Hierarchical warping of one point of [0,1)^2.
  WisSample warp(glm::dvec2 u) const;
  double pixelProbability(uint64_t pixel) const;
  double pdf(const glm::vec3& worldDir) const;
  // The approximated product (env average x f cos at the leaf centre), RGB.
  glm::vec3 approximateProduct(uint64_t pixel) const;
  // Weight of the children of `node` at level `level` (children at level+1).
  std::array<double, 4> childWeights(int level, uint64_t node) const;
  // Sum of the face weights (a positive multiple of the approximated product's integral).
  double faceWeight(int face) const { return top_[face]; }

 private:
  double leafWeight(int level, uint64_t node) const;

  const Environment& env_;
  HealpixFrameBrdf brdf_;
  const std::vector<glm::vec3>& centers_;
  int order_;
  int exactLevel_;
  float floor_;
  double total_ = 0.0;
  std::vector<double> top_;  // levels 0..exactLevel_, flat layout
  mutable std::unordered_map<uint64_t, std::array<double, 4>> memo_;
};

// The `wis` (unbiased f/p) and `wis-biased` estimates with `spp` warped
// points, one per sample (with the stratified sampler, one scrambled
// (0,2)-sequence).
glm::vec3 estimateWis(const Scene& scene, const ShadingPoint& sp, int spp, int order, bool biased,
                      const std::vector<glm::vec3>& centers, PixelSampler& sampler, EstimateCounters& counters);

}  // namespace ht
