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
// 2. Give each node the mass E x c and order the nodes by the colour of
//    their light (their mean radiance's blue-red balance), so that the
//    stratified points below spread over light of each colour in proportion;
//    place n_t systematic points (i + u) / n_t on the mass CDF in that order.
// 3. Inside a node the point's remaining coordinate descends to a leaf,
//    each child drawn by its environment average x BRDF x cos at its light's
//    centroid x its visibility class (down to a level, by the environment alone
//    below), and two fresh numbers place it inside the leaf.
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
// A flat surface with a specular lobe samples its diffuse lobe's shared
// table, and the lobe by the BRDF's own sampler of it: a per-point table
// is far coarser than a narrow lobe, above all at grazing views, where
// Fresnel makes the lobe most of what the surface reflects. The lobe's
// share of the n directions follows its estimated share of the light
// (frontierLobeCount), and the balance heuristic combines the two.
//
// The estimate is sum f(w) / (n_t p_t(w) + n_b p_b(w)) over all n directions,
// plus a control variate on colour. The density follows luminance, so each
// channel's f / p varies with the chroma (radiance / luminance) of the light
// it hits. Each table direction drawn in node k adds
// M / n x (mu - kappa_k chroma): its chroma (its leaf's where the node is
// free and its descent exact for colour, else its node's), M the point's
// total mass, kappa_k the node's f / p per unit of chroma and of mass (the
// BRDF's colour at the node's centroid over the node's factor c; on a
// shared table, the albedo / pi x centre / c) and mu the mean of
// kappa_k chroma, which the table gives exactly
// (FrontierOptions::colourControl). Its mean is 0. A channel the term
// would take below 0 is set to 0, which happens rarely and only where the
// channel is dark (docs/ht.md).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

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
  // ... or, in a point's own table, >= brdfFloor x its diffuse lobe's bound +
  // this x its specular lobe's, where the descent resolves the specular lobe
  // (frontierLobeFloor).
  float lobeFloor = 0.05f;
  // A node the caps cover in part weighs its estimated visible share
  // (frontierVisibility), never less than this: an underestimate gives its
  // visible part too little mass (large f / p).
  float minPartialVisibility = 0.1f;
  float coarseRatio = 4.0f;     // a node is coarse for the BRDF when B > this x its centre value
  float maxBrdfShare = 0.5f;    // at most this share of the n directions from the BRDF
  bool visibility = true;       // caps in the density
  // Below a table node, children are drawn by environment x BRDF x
  // visibility down to this level, by the environment x visibility below it
  // (in a point's own table, deeper for a narrow lobe: frontierProductLevel).
  int productLevel = 5;
  bool colourOrder = true;      // the CDF's nodes by colour (else along the nested index)
  bool colourControl = true;    // the control variate on colour
};

// A spherical cap of blocked directions seen from a shading point (HEALPix
// frame). Per level: a node whose centre has cos(centre, axis) >= cosInside
// lies inside it, one with <= cosOutside outside it.
struct LightCap {
  glm::vec3 axis;
  std::array<float, 32> cosInside, cosOutside;
};

// The cap of an occluder (HEALPix frame axis, sine of its half-angle)
// less a margin for rounding (kCapMargin), with its thresholds at every
// level of g; false where nothing is left of it.
bool frontierCap(const glm::vec3& axis, float sinHalfAngle, const HtGeometry& g, LightCap& cap);

// The visibility of a node of `level` at `centre` under `caps`: its class
// (0 inside a cap, 1 outside every cap, 2 partly covered) and its factor in
// the density: 0, 1, or for a partly covered node its visible share under
// the cap that covers most of it, the covered share taken linear in cos
// between the cap's outside and inside thresholds; at least `minPartial`.
// Caps overlap (a ball on a plane), so the smallest share, not a product.
int frontierVisibility(const std::vector<LightCap>& caps, const glm::vec3& centre, int level, float minPartial,
                       float& factor);
// Nodes down to this level are large against the caps: a partly covered
// one weighs the mean of its four children's factors (0 for a child inside
// a cap), a finer estimate of the share the caps leave.
constexpr int kFrontierShareLevel = 3;
// frontierVisibility of node `node` of `level` (geometry g), with that
// finer factor where it is partly covered and coarse.
int frontierNodeVisibility(const std::vector<LightCap>& caps, const HtGeometry& g, int level, uint64_t node,
                           float minPartial, float& factor);

// The colour bins that order a frontier's CDF.
constexpr int kFrontierColourBins = 16;
// Per node of the environment's average tree (its layout):
// - `bins`, its colour bin: (blue - red) / (red + green + blue) of its mean
//   radiance, from -1 to 1 in kFrontierColourBins equal steps (the middle
//   one where it is black);
// - `chroma` (the levels above the leaves only), its radiance over its
//   luminance, both summed over its leaves: the mean of frontierLeafChroma
//   over a descent by the average tree (0 where it is black);
// - `centroid` (the levels above the leaves only), the direction of its
//   light: its leaves' centres weighted by their luminance, summed and
//   normalised (its centre where it is black). A table reads a node's BRDF
//   factor there, not at its centre: where a small bright source sits off
//   the centre of a large node, the BRDF at the source is what its mass
//   needs.
struct FrontierColours {
  std::vector<uint8_t> bins;
  std::vector<glm::vec3> chroma;
  std::vector<glm::vec3> centroid;
};
// `g`: the geometry of the map's order.
FrontierColours frontierColours(const Environment& env, const HtGeometry& g);
// The direction node i (tree layout) reads its BRDF factor in: its
// centroid above the leaves, a leaf's centre.
inline const glm::vec3& frontierFactorDirection(const FrontierColours& colours, const HtGeometry& g, uint64_t i) {
  return i < colours.centroid.size() ? colours.centroid[i] : g.centers[i];
}
// A leaf's radiance over its luminance (0 where it is black).
glm::dvec3 frontierLeafChroma(const glm::vec3& radiance);

struct FrontierNode {
  int level;
  uint64_t node;
  uint64_t firstLeaf;  // nested index of its first leaf at the environment's order
  glm::vec3 centre;    // HEALPix frame
  double mass;         // E x c
  float brdfBound;     // B
  float brdfCentre;    // BRDF x cos at the centre
  int visibility;      // class under the caps the table was built with: 1 free, 2 partly covered
  glm::vec3 chroma;    // FrontierColours::chroma of the node
  // The mean chroma of the leaf a free descent from the node reaches, where
  // `exactColour` (a shared table's nodes, and below the descent's product
  // levels, where it follows the average tree); else `chroma`.
  glm::vec3 descentChroma;
  bool exactColour;
  // A direction's f / p per unit of its chroma and of the table's mass M
  // where the node's factor holds: the BRDF's colour at the centroid over c
  // in an own table; centre / c in a shared one (whose mass leaves out the
  // albedo / pi).
  glm::vec3 kappa{1.0f};
};

// Nodes sorted along the nested index, with their masses, and the order of
// the CDF: by segment (colour bin, then face), along the nested index
// inside each.
struct FrontierTable {
  static constexpr int kSegments = kFrontierColourBins * 12;
  std::vector<FrontierNode> nodes;
  std::vector<uint32_t> cdfOrder;                 // node indices in CDF order
  std::vector<double> cum;                        // cum[i]: mass before position i (cdfOrder.size() + 1 entries)
  std::array<uint32_t, kSegments + 1> segStart{};  // first position of each segment, and the end
  std::array<uint32_t, 13> faceStart{};           // first node of each face, and the end
  double coarseShare = 0.0;  // share of the mass in nodes coarse for the BRDF
  int splits = 0;
  // Per face: sums over its nodes, along the nested index, of mass x the
  // mean chroma of their directions (Frontier::colourMean; xyz) and of mass
  // (w).
  std::array<glm::dvec4, 12> faceColour{};
};

// The frontier a shading point samples: a table and the point's own masses.
class Frontier {
 public:
  // Prepares the frontier at `point` for n samples, reusing this object's
  // storage and, on a flat surface, the calling thread's shared tables (one
  // stays valid until the thread builds a frontier under another
  // environment, or more than kFrontierSharedTables of them).
  // `point` is `sp` seen by HT (its visibility caps are not used);
  // `colours`: frontierColours of the point's environment.
  void build(const HtPoint& point, const ShadingPoint& sp, const FrontierOptions& options, int n,
             const FrontierColours& colours);

  const FrontierTable& table() const { return *table_; }
  double totalMass() const { return total_; }
  double coarseShare() const { return table_->coarseShare; }
  bool shared() const { return table_ != &own_; }
  // The table is the diffuse lobe's shared table and the BRDF technique
  // samples the specular lobe alone (a flat surface that is not Lambert).
  bool specularApart() const { return specularApart_; }
  int splits() const { return table_->splits; }
  size_t size() const { return table_->nodes.size(); }

  // Draws the direction of the point x in [0, 1) of the mass CDF (HEALPix
  // frame); `jitter` places it inside its leaf. Returns the leaf; `node`,
  // when given, receives the table node it lies in.
  uint64_t sample(double x, const glm::vec2& jitter, glm::dvec3& dirHp, double& pdf, size_t* node = nullptr) const;
  // Density of the direction in `leaf` (0 outside the frontier).
  double pdf(uint64_t leaf) const;

  // The control variate on colour: a direction drawn in node k that
  // reaches `leaf` has kappa_k x its chroma, colourOf(k, leaf) (its leaf's
  // chroma where the node is free and exactColour, else the node's), whose
  // mean over the node's directions is colourMean(k) (kappa_k x
  // descentChroma where it is free, else x its chroma); `colourAverage` is
  // the mass-weighted mean of the means. All three hold where
  // `colourControl` (FrontierOptions::colourControl).
  bool colourControl() const { return colour_; }
  glm::dvec3 colourOf(size_t k, uint64_t leaf) const;
  glm::dvec3 colourMean(size_t k) const;
  const glm::dvec3& colourAverage() const { return colourAverage_; }

 private:
  const HtPoint* point_ = nullptr;
  const FrontierColours* colours_ = nullptr;
  int order_ = 0;
  int productLevel_ = 0;
  float brdfFloor_ = 0.0f, minPartialVisibility_ = 1.0f;
  bool cosFactor_ = false;  // the BRDF factor is cos+ (up to a constant)
  bool specularApart_ = false;
  FrontierTable own_;
  const FrontierTable* table_ = &own_;
  std::vector<LightCap> caps_;  // the caps the descent applies
  // This point's masses and visibility classes differ from the table's on
  // the faces in `touched_` (a shared table under the point's caps); there
  // `mass_` and `class_` hold them, by node, and `cum_` the masses' prefix
  // sums from the start of each segment, by CDF position.
  uint32_t touched_ = 0;
  std::vector<double> mass_, cum_;
  std::vector<uint8_t> class_;
  std::array<double, FrontierTable::kSegments + 1> segCum_{};  // mass of the segments before each
  double total_ = 0.0;
  glm::dvec3 colourAverage_{0.0};
  bool colour_ = false;

  bool touched(const FrontierNode& nd) const { return touched_ >> (nd.node >> (2 * nd.level)) & 1u; }
  double mass(size_t k) const;
  int visibility(size_t k) const;
  size_t nodeOfLeaf(uint64_t leaf) const;
  double density(size_t k, uint64_t leaf) const;
  // The four children of `parent` (at `level`): their weights, and their
  // visibility classes from the parent's.
  void children(int level, uint64_t parent, int parentClass, double w[4], int cls[4]) const;
};

// Shared tables one thread keeps at most, and the bytes of one at the default
// size (nodes, CDF order and prefix sums).
constexpr uint64_t kFrontierSharedTables = 64;
constexpr uint64_t kFrontierSharedTableBytes =
    (3 * kFrontierSharedRefinements + 12) * (sizeof(FrontierNode) + sizeof(uint32_t) + sizeof(double));

// The material less its diffuse lobe.
Material specularLobeOf(const Material& m);
// The level of the environment's average around the mirror direction that
// frontierLobeCount reads.
constexpr int kFrontierLobeLevel = 3;
// The n_s of n directions that sample the specular lobe where the table is
// the diffuse lobe's: n S / (S + D), rounded, at least 1 where S > 0 and
// n >= 2, at most n - 1. S: the lobe's reflectance at cos(theta_o)
// (Schlick for GGX, the specular colour for Phong, in luminance) x
// `mirrorRadiance`, the environment's average around the mirror direction;
// D: the diffuse albedo / pi x the table's mass, the irradiance it
// estimates. A lobe without directions of its own would leave its peak to
// the table's cos+, which can be tiny there: rare directions with a huge
// f / p, a tail that no affordable count of estimates averages out.
int frontierLobeCount(const Material& m, float cosO, float mirrorRadiance, double tableMass, int n);
// For n = 1, where one direction cannot be split between the table and the
// lobe: the probability q that it samples the lobe, S / (S + D) kept within
// [1/8, 7/8] (0 where S = 0). The direction comes from the mixture, the
// table with probability 1 - q, and is weighed by the balance heuristic
// over the probabilities (one-sample MIS).
constexpr double kFrontierMixtureMin = 0.125;  // exact in float and double
double frontierLobeMixture(const Material& m, float cosO, float mirrorRadiance, double tableMass);

// A level's nodes resolve a specular lobe whose half-width (GGX alpha,
// Phong sqrt(2 / exponent) / 2) is at least this many times their radius:
// a node's diameter.
constexpr float kFrontierLobeRadii = 2.0f;
// The last level whose children a point's own table weighs by the BRDF:
// options.productLevel, or deeper, down to the map's order, until its
// nodes resolve the specular lobe. A narrow lobe (chrome, GGX alpha 0.02)
// left to the environment below level 5 gets directions where it is dark.
int frontierProductLevel(const Material& m, const HtGeometry& g, const FrontierOptions& options);
// The floor of a point's specular lobe in its own table: lobeFloor where
// the nodes of `productLevel` (frontierProductLevel) resolve the lobe,
// brdfFloor where it is narrower, and for a Lambert. A node's factor is
// read at its light's centroid; the floor guards against a lobe that peaks
// between the points read, which only a lobe narrower than the nodes the
// descent weighs can do. Against the BRDF's bound, a floor of 0.25 gives a
// wide glossy lobe's flanks far more mass than their light (docs/ht.md).
float frontierLobeFloor(const Material& m, const HtGeometry& g, const FrontierOptions& options, int productLevel);

// The splits a per-point frontier makes for n samples.
int frontierRefinements(const FrontierOptions& options, int n);
// The n_b of n directions that come from BRDF sampling (of a table whose
// share of mass in nodes coarse for the BRDF is `coarseShare`).
int frontierBrdfCount(const Frontier& frontier, const FrontierOptions& options, int n);
int frontierBrdfCount(double coarseShare, const FrontierOptions& options, int n);

// A flat surface's shared Lambert table: `n` is the surface's normal as a
// shading point sees it (frontierSurfaceNormal of the world normal).
glm::vec3 frontierSurfaceNormal(const Environment& env, const glm::vec3& normal);
void buildSharedFrontierTable(const Environment& env, const HtGeometry& geometry, const glm::vec3& n,
                              const FrontierOptions& options, const FrontierColours& colours, FrontierTable& table);

// HT frontier estimate at a shading point with exactly n directions.
// `tables`: the geometry of the map's order and the frontier's colours.
glm::vec3 estimateHtFrontier(const Scene& scene, const ShadingPoint& sp, const FrontierOptions& options, int n,
                             Rng& rng, PixelSampler& sampler, EstimateCounters& counters, const MethodTables& tables);

}  // namespace ht
