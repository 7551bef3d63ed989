// HT frontier: product importance sampling with a fixed sample count.
//
// The seed's HT estimator draws a random number of samples N, and Var(N)
// carries almost all of its variance (docs/ht.md). This method keeps HT's
// density model (the max/avg trees, the BRDF cone bounds and the
// inner-sphere visibility caps) but draws exactly n directions:
//
// 1. Refine an adaptive frontier of HEALPix nodes, always splitting the node
//    whose non-environment factor is least certain: priority
//    E (B - c)^2 / c, with E the node's environment energy, B the bound of
//    BRDF x cos over it and c the estimate of BRDF x cos x visibility at its
//    centre (never below a floor of B, so the density stays positive
//    wherever the integrand can be).
// 2. Give each node the mass E x c, order the nodes along the nested index
//    and place n_t systematic points (i + u) / n_t on the mass CDF.
// 3. Inside a node the point's remaining coordinate descends the
//    environment's average tree to a leaf (density proportional to the
//    radiance), and two fresh numbers place it inside the leaf.
// 4. Where the frontier is coarse for the BRDF (its mass sits in nodes with
//    B much above c), n_b of the n directions are BRDF samples instead, and
//    all n are combined by the balance heuristic, which stays unbiased with
//    stratified points because it sums over the techniques' fixed counts.
//
// Lambert tables do not depend on wo, and their shape not on the albedo: on
// a flat surface every point has the same table but for visibility. It is
// refined once per normal (and thread), further than a point's own table,
// and each point applies its own visibility caps to its nodes. The table is
// a function of the normal and the environment alone, so sharing never
// changes an image.
//
// The estimate is sum f(w) / (n_t p_t(w) + n_b p_b(w)) over all n directions.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "ht.h"

namespace ht {

// Splits of a flat surface's shared Lambert table, by default.
constexpr int kFrontierSharedRefinements = 192;

struct FrontierOptions {
  // At most this many node splits per shading point; < 0: 16 + n, at most
  // 256, for n samples (measured best at 4 to 64 spp on the test scenes).
  int refinements = -1;
  int sharedRefinements = kFrontierSharedRefinements;  // a flat surface's shared table (< 0: not shared)
  float brdfFloor = 0.25f;      // node BRDF factor >= this x its bound
  // Visibility factor of a node the caps cover in part. Low values give its
  // visible part too little mass (large f / p); 0.85 measured best.
  float partialVisibility = 0.85f;
  float coarseRatio = 4.0f;     // a node is coarse for the BRDF when B > this x its centre value
  float maxBrdfShare = 0.5f;    // at most this share of the n directions from the BRDF
  bool visibility = true;       // caps in the density
};

struct FrontierNode {
  int level;
  uint64_t node;
  uint64_t firstLeaf;  // nested index of its first leaf at the environment's order
  glm::vec3 centre;    // HEALPix frame
  double mass;         // E x c
  float brdfBound;     // B
  float brdfCentre;    // BRDF x cos at the centre
};

// Nodes sorted along the nested index (so each face's nodes are one run),
// with their masses.
struct FrontierTable {
  std::vector<FrontierNode> nodes;
  std::vector<double> cum;              // cum[k]: mass of the nodes before k (nodes.size() + 1 entries)
  std::array<uint32_t, 13> faceStart{};  // the first node of each face, and the end
  double coarseShare = 0.0;  // share of the mass in nodes coarse for the BRDF
  int splits = 0;
};

// The frontier a shading point samples: a table and the point's own masses.
class Frontier {
 public:
  // Prepares the frontier at `point` for n samples, reusing this object's
  // storage and, on a flat surface, the calling thread's shared tables.
  // `point` is `sp` seen by HT (its visibility caps are not used).
  void build(const HtPoint& point, const ShadingPoint& sp, const FrontierOptions& options, int n);

  const FrontierTable& table() const { return *table_; }
  double totalMass() const { return total_; }
  double coarseShare() const { return table_->coarseShare; }
  bool shared() const { return table_ != &own_; }
  int splits() const { return table_->splits; }
  size_t size() const { return table_->nodes.size(); }

  // Draws the direction of the point x in [0, 1) of the mass CDF (HEALPix
  // frame); `jitter` places it inside its leaf. Returns the leaf.
  uint64_t sample(double x, const glm::vec2& jitter, glm::dvec3& dirHp, double& pdf) const;
  // Density of the direction in `leaf` (0 outside the frontier).
  double pdf(uint64_t leaf) const;

 private:
  const HtPoint* point_ = nullptr;
  int order_ = 0;
  FrontierTable own_;
  const FrontierTable* table_ = &own_;
  // This point's masses differ from the table's on the faces in `touched_`
  // (a shared table under the point's caps); there `mass_` holds them and
  // `cum_` their prefix sums from the face's first node.
  uint32_t touched_ = 0;
  std::vector<double> mass_, cum_;
  std::array<double, 13> faceCum_{};  // mass of the faces before each face
  double total_ = 0.0;

  static int faceOf(const FrontierNode& nd) { return int(nd.node >> (2 * nd.level)); }
  double mass(size_t k) const;
  // Mass of the nodes of k's face before k.
  double cumInFace(size_t k, int face) const;
  size_t nodeOfLeaf(uint64_t leaf) const;
  double density(size_t k, uint64_t leaf) const;
};

// Shared tables one thread keeps at most, and the bytes of one at the default
// size (nodes and prefix sums).
constexpr uint64_t kFrontierSharedTables = 64;
constexpr uint64_t kFrontierSharedTableBytes = (3 * kFrontierSharedRefinements + 12) * (sizeof(FrontierNode) + 8);

// The splits a per-point frontier makes for n samples.
int frontierRefinements(const FrontierOptions& options, int n);
// The n_b of n directions that come from BRDF sampling.
int frontierBrdfCount(const Frontier& frontier, const FrontierOptions& options, int n);

// HT frontier estimate at a shading point with exactly n directions.
glm::vec3 estimateHtFrontier(const Scene& scene, const ShadingPoint& sp, const FrontierOptions& options, int n,
                             Rng& rng, PixelSampler& sampler, EstimateCounters& counters, const MethodTables& tables);

}  // namespace ht
