// Two-stage importance sampling (TSIS; Cline, Talbot, Egbert, Cardon,
// EGSR 2006) on the HEALPix map.
//
// The 2D domain is the HEALPix projection itself: twelve base faces, each a
// square grid of Nside x Nside pixels (ix, iy). The projection is equal-area,
// so a rectangle of pixels has the solid angle of its pixel count and a
// summed-area table (SAT) of the luminance per face gives the exact
// integral of the environment over any rectangle, with no resampling and
// no Jacobian. The SAT is built once per environment and cached.
//
// Per shading point (stage 1), the domain is partitioned by a BRDF-driven
// kd-split of the faces into at most `regions` rectangles: the rectangle
// with the largest E(R) (b_max - b_min) is halved across its longer side,
// where E(R) is its SAT integral and b the BRDF luminance (f cos) at its
// centre, its corners and the BRDF's peak directions when they fall inside.
// Each rectangle gets the weight E(R) (mean of those b + a small floor).
// Stage 2 warps a stratified point: x picks a rectangle by weight, then
// (rescaled) a column of it by the SAT's column sums; y picks a row inside
// that column; what is left of (x, y) places the direction inside the
// pixel. The density is exact for every direction:
//   p(w) = P(R(w)) L(w) / (E(R(w)) pixel solid angle).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "environment.h"
#include "shading.h"
#include "sampler.h"
#include "scene.h"
#include "wis.h"

namespace ht {

// Per-face summed-area tables of the environment's luminance at `level`
// (the map's order, at most kMaxLevel or the level asked for; deeper maps
// are sampled below the SAT's pixels by their average tree).
struct TsisTable {
  static constexpr int kMaxLevel = 9;
  int level = 0;
  uint32_t nside = 1;
  std::vector<double> sat;  // per face (nside+1)^2: sum over ix < x, iy < y

  double at(int face, uint32_t x, uint32_t y) const {
    return sat[(size_t(face) * (nside + 1) + y) * (nside + 1) + x];
  }
  // Sum over the pixels x0 <= ix < x1, y0 <= iy < y1 of one face.
  double rect(int face, uint32_t x0, uint32_t y0, uint32_t x1, uint32_t y1) const {
    return at(face, x1, y1) - at(face, x0, y1) - at(face, x1, y0) + at(face, x0, y0);
  }
};
TsisTable buildTsisTable(const Environment& env, int maxLevel = TsisTable::kMaxLevel);

struct TsisRegion {
  int face;
  uint32_t x0, y0, x1, y1;  // pixel rectangle [x0, x1) x [y0, y1) at the SAT level
  double energy;            // SAT sum of luminance over it
  double brdf;              // BRDF estimate (mean of the evaluated points + floor)
  double probability;       // of choosing it in stage 1
};

struct TsisSample {
  glm::vec3 dir;  // world space
  uint64_t pixel; // environment pixel (map order)
  int region;
  double pdf;     // solid-angle density
};

class TsisPoint {
 public:
  static constexpr int kDefaultRegions = 32;
  static constexpr float kBrdfFloor = 1e-3f;  // BRDF weight >= this x HealpixFrameBrdf::scale()

  // `table`: buildTsisTable of this environment.
  TsisPoint(const Environment& env, std::shared_ptr<const TsisTable> table, const Material& m,
            const glm::vec3& normalWorld, const glm::vec3& woWorld, int maxRegions = kDefaultRegions);

  bool empty() const { return !(total_ > 0.0); }
  const std::vector<TsisRegion>& regions() const { return regions_; }
  const TsisTable& table() const { return *table_; }

  TsisSample warp(glm::dvec2 u) const;
  double pdf(const glm::vec3& worldDir) const;
  // Index of the region holding a pixel at the SAT level, -1 if none.
  int regionOf(uint64_t satPixel) const;

 private:
  const Environment& env_;
  std::shared_ptr<const TsisTable> table_;
  std::vector<TsisRegion> regions_;
  std::vector<double> cdf_;  // cumulative region weights, cdf_.back() = total_
  double total_ = 0.0;
};

// The `tsis` estimate: `spp` points, one per sample (with the stratified
// sampler, one scrambled (0,2)-sequence), warped through the two stages,
// f / p each.
glm::vec3 estimateTsis(const Scene& scene, const ShadingPoint& sp, int spp, const std::shared_ptr<const TsisTable>& table,
                       PixelSampler& sampler, EstimateCounters& counters);

}  // namespace ht
