// ht-cut: product importance sampling over a fixed cut of HT's tree, in
// the shape a GPU runs well.
//
// The host cuts the environment's average tree once per map: K nodes,
// refined from the base faces by splitting the node of largest power
// (average luminance x solid angle) until there are K or the nodes reach
// kCutMaxLevel. A shading point weighs every node of the cut in one loop of
// K passes, the same loop for every pixel (CutPoint::weight):
//
//   w_k = (diffuse / pi x D_k + P_k x specular f cos at the light's centroid) x v_k
//
// with P_k the node's power, D_k its light's integral of cos+ (its first
// moment dotted with the normal, exact above the horizon: cos is linear in
// the direction), v_k its visible share under the point's caps. Where the
// horizon or a cap cuts a node of the cut, its weight is its four
// children's. n_c of the n directions are systematic points on the prefix
// sums of w; below its node a direction descends by the children's weights
// down to CutOptions::productLevel, by the average tree below. The other
// n_b come from the BRDF (the specular lobe alone where the weights hold the
// diffuse lobe), and all n are combined by the balance heuristic,
//
//   sum f(w) / (n_c p_c(w) + n_b p_b(w)),
//
// plus a control variate on colour. A pure diffuse point has n_b = 0: its
// weights stay positive wherever its integrand can be (kCutHorizonFloor).
// Elsewhere p_b covers every direction where f cos is positive, so that p_c
// may be zero there. A direction's p_c needs its node: a table at
// kCutMaxLevel maps each node of that level to the cut node holding it.
//
// No heap, no per-point table, no search longer than log K: every pixel
// runs the same loops.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "bsdf.h"
#include "common.h"
#include "env_sampler.h"
#include "environment.h"
#include "ht_frontier.h"
#include "integrator.h"
#include "sampler.h"
#include "shading.h"

namespace ht {

struct Rng;

constexpr int kCutMaxLevel = HT_CUT_MAX_LEVEL;
// The deepest level whose nodes a point weighs: a cut node's children.
constexpr int kCutMomentLevel = kCutMaxLevel + 1;
// A node's weight is at least this share of its power x the cos of its
// bounding cone's highest point, where that point lies above the horizon.
constexpr float kCutHorizonFloor = HT_CUT_HORIZON_FLOOR;
// Either technique's share of a point with both lobes, at least.
constexpr float kCutMinShare = HT_CUT_MIN_SHARE;

// The sine of the radius of a disc of a node's solid angle at `level`.
float cutDiscSin(int level);
// The mean of cos+ over a small disc of radius R whose centre lies at
// elevation E, from sin E and sin R: sin R x m(sin E / sin R), m the
// clipped disc's exact mean approximated by (1 + a)^2 / 4 x (89/128 +
// 39/256 (1 + a)) (within 0.023 of it; exact at a = -1 and 1; the constants
// exact in float, as the shader's literals must be).
inline float cutClippedCosine(float sinE, float sinR) {
  const float a = sinE / sinR;
  const float b = 1.0f + a;
  const float c = 0.6953125f + 0.15234375f * b;
  return sinR * ((0.25f * b * b) * c);
}
// The share of a disc beyond a straight edge, x in [0, 1] the depth it
// reaches past the edge over its diameter: the circular segment's exact
// (t - sin t) / 2 pi, t = 2 acos(1 - 2 x), approximated by x^1.5 (869/512 -
// 145/256 x) up to x = 1/2 and by symmetry above (within 0.0016; right in
// order at both ends, where a smoothstep's x^2 gives a disc barely past the
// edge a fifth of its share).
inline float cutSegmentShare(float x) {
  const float a = std::min(x, 1.0f - x);
  const float f = (a * std::sqrt(a)) * (1.697265625f - 0.56640625f * a);
  return x <= 0.5f ? f : 1.0f - f;
}

struct CutNode {
  int level;
  uint64_t node;
  glm::vec3 chroma;  // its light's radiance over luminance, both summed over its leaves
};

// A node's light as the weights read it (HEALPix frame): its bounding
// disc's centre, power (average luminance x solid angle), first moment and
// level.
struct CutLight {
  glm::vec3 centre;
  float power;
  glm::vec3 moment;
  int level;
};

// Lights grouped by level, a column per quantity (entries levelBegin[l]
// to levelBegin[l + 1] of level l): a point weighs them in one loop per
// level, which compilers vectorise.
struct CutColumns {
  std::vector<float> x, y, z, power, mx, my, mz;  // centre, power, first moment
  std::vector<size_t> levelBegin;
  // The columns of `lights` (levels below kCutMomentLevel + 1), and in
  // entry each light's entry.
  void fill(const CutLight* lights, size_t count, std::vector<uint32_t>& entry);
};

struct EnvCut {
  std::vector<CutNode> nodes;    // along the nested index
  // The nodes' lights, then each one's four children's (K + 4k + j; zero
  // power below momentLevel): what the loop over the cut and the descent's
  // first step read.
  std::vector<CutLight> lights;
  // The K nodes' lights again as columns, and each one's entry there.
  CutColumns columns;
  std::vector<uint32_t> entry;
  int lookupLevel = 0;           // min(kCutMaxLevel, the map's order)
  std::vector<uint32_t> lookup;  // per node of lookupLevel: the cut node holding it
  int momentLevel = 0;           // min(kCutMomentLevel, the map's order)
  // Per tree node down to momentLevel (the tree's layout): the first moment
  // of its light, luminance x solid angle x centre summed over its leaves
  // (HEALPix frame).
  std::vector<glm::vec3> moment;
  // Per tree node down to momentLevel: the chroma of its light (its
  // radiance over its luminance, summed over its leaves).
  std::vector<glm::vec3> chroma;
  std::array<float, 32> discSin{};    // cutDiscSin per level
  std::array<float, 32> discChord{};  // the chord radius of that disc
  std::array<float, 32> omega{};      // a node's solid angle per level
  // Node `at` (the tree's layout) of `level` <= momentLevel.
  CutLight light(const MaxAvgTree& tree, const HtGeometry& g, int level, uint64_t at) const {
    return {g.centers[at], omega[size_t(level)] * tree.avgv[at], moment[at], level};
  }
  uint32_t cutNodeOf(const Environment& env, uint64_t pixel) const {
    return lookup[pixel >> (2 * (env.order - lookupLevel))];
  }
};

// The cut of `nodes` nodes (12 to HT_CUT_MAX_NODES); `g`: the map's order.
EnvCut buildEnvCut(const Environment& env, const HtGeometry& g, int nodes);

// The cut's size for n directions per point where none is asked for
// (nodes < 0; n = 0 where n is not known): 8 n within [192,
// HT_CUT_MAX_NODES]. Weighing the cut is a fixed cost per point: at more
// directions per point a finer cut pays for itself.
inline int cutNodesFor(int nodes, int n) {
  return nodes >= 0 ? nodes : std::clamp(8 * std::max(n, 0), 192, HT_CUT_MAX_NODES);
}

// A lobe alone's share of its n directions drawn from the BRDF,
// rho / (rho + w) within [1/4, 3/4]: w the lobe's width (GGX alpha; Phong
// 1 / (2 sqrt(exponent + 1)), its spread about the mirror direction being
// twice GGX's alpha's), rho the bounding diameter of the descent's finest
// nodes. The cut's directions follow a lobe as far as its nodes resolve it;
// a narrower one is left more to the BRDF.
inline float cutLobeShare(const Material& m, float rho) {
  const float width = m.type == MaterialType::Phong ? 0.5f / std::sqrt(m.exponent + 1.0f) : m.alpha;
  return std::clamp(rho / (rho + width), 0.25f, 0.75f);
}

struct CutOptions {
  float minPartialVisibility = 0.03f;  // a partly covered node's visible share, at least
  int productLevel = 6;                // children by their weights down to this level
  bool visibility = true;              // the caps in the weights
  bool colourControl = true;           // the control variate on colour
};

// cutLobeShare's rho for `options`: twice the bounding radius (sine) of
// the descent's finest nodes, the span a lobe must reach across to be
// resolved by more than one of them.
inline float cutLobeSpan(const CutOptions& options, const EnvCut& cut, const HtGeometry& g) {
  return 2.0f * g.levelSinRadius[size_t(std::clamp(options.productLevel, 0, cut.momentLevel))];
}

struct MethodOptions;
// ht-cut's options for a render's method options.
CutOptions cutOptionsFor(const MethodOptions& options);

// The caps a point keeps at most: the first entries of occluders with this
// many slots, the largest spheres' and the planes' (but the one it lies on).
constexpr size_t kCutMaxCaps = HT_CUT_MAX_CAPS;
static_assert(kCutMaxCaps <= kMaxCaps);

// A point's caps, a column per quantity, kCutMaxCaps wide so that their
// tests run as one loop of fixed length: axes, the chords of their radii,
// and frontierCap's thresholds per level (entry level x kCutMaxCaps + cap).
// The slots past count hold thresholds no node reaches.
struct CutCaps {
  int count = 0;
  std::array<float, kCutMaxCaps> x{}, y{}, z{}, chord{};
  std::vector<float> inside, outside;
};

// What weighs the tree's nodes at one shading point (HEALPix frame).
struct CutPoint {
  CutPoint(const Scene& scene, const ShadingPoint& sp, const Shading& sh, const CutOptions& options,
           const EnvCut& cut, const HtGeometry& g);
  // Node `at` (the tree's layout) of `level` <= cut.momentLevel; withLobe:
  // a lobe alone's, read at the light's centroid. `uncertain`, if given, is
  // set where the horizon or a cap cuts the node.
  float weight(int level, uint64_t at, bool withLobe, bool* uncertain = nullptr) const {
    return weight(cut.light(tree, g, level, at), withLobe, uncertain);
  }
  float weight(const CutLight& n, bool withLobe, bool* uncertain = nullptr) const;
  // The share of a node of `level` centred at `centre` that the cap
  // reaching deepest into it leaves open, of those covering it in part (1
  // where none does).
  float visibleShare(const glm::vec3& centre, int level) const;
  // A diffuse point's weights (weight without the lobe) of the columns'
  // entries, all but the shares visibleShare gives: w[i] the weight where
  // no cap covers the node in part, else before that share (0 where a cap
  // covers it); flags[i] bit 0 where the horizon cuts it, bit 1 where a
  // cap covers it in part.
  void openWeights(const CutColumns& columns, float* w, int32_t* flags) const;
  // weight(n, false, uncertain) of the columns' entry i from openWeights.
  float diffuseWeight(const CutColumns& columns, size_t i, int level, float w, int32_t flags, bool* uncertain) const;

  const EnvCut& cut;
  const HtGeometry& g;
  const MaxAvgTree& tree;
  float minPartial;
  glm::vec3 s, t, normal;  // the shading frame
  glm::vec3 woLocal;
  float diffuse;  // luminance of the diffuse albedo / pi
  bool apart;     // a diffuse and a specular lobe: the weights hold the diffuse one
  bool lobeOnly;  // a specular lobe alone
  Material lobe;     // the material without its diffuse lobe
  CutCaps caps;
};

// The density a point samples its cut directions from: the cut's prefix
// sums over the point's weights, and below a node the children by their
// weights down to productLevel, by the average tree below.
class CutDensity {
 public:
  // Weighs the cut at `point` (which it keeps a reference to), reusing its storage.
  void reset(const CutPoint& point, const Environment& env, const CutOptions& options);
  float total() const { return total_; }
  // The mean chroma of the node drawn: the nodes' chroma by their probabilities.
  glm::vec3 colourMean() const { return colourMean_; }
  // The node whose prefix sums hold x * total (x in [0, 1)).
  uint32_t node(double x) const;
  double nodeProbability(uint32_t k) const;
  // A direction below node k from u; its pdf: p_c's solid-angle density.
  // colourDrift, where asked for: over the descent's steps, the chroma each
  // step draws on average less that of the child it drew, and the last
  // node's chroma less the pixel's; each term has mean 0 given the steps
  // before it.
  EnvSample sample(uint32_t k, glm::dvec2 u, glm::dvec3* colourDrift = nullptr) const;
  // p_c of a direction in `pixel` (solid angle).
  float pdf(uint64_t pixel) const;

 private:
  void childWeights(int level, uint64_t parent, float (&w)[4]) const;
  // childWeights of cut node k's children, kept from reset where it
  // weighed them.
  void firstChildWeights(uint32_t k, float (&w)[4]) const;
  // Cut node k's weight w where children_ holds its children's: theirs, if
  // they weigh anything.
  float keepChildren(uint32_t k, float w);
  const CutPoint* point_ = nullptr;
  const Environment* env_ = nullptr;
  int productLevel_ = 0;
  std::vector<float> cum_;  // cum_[k]: the weights before node k; node k's is cum_[k + 1] - cum_[k]
  std::vector<float> children_;  // 4k + j: cut node k's children's weights where kept
  std::vector<uint8_t> kept_;    // per cut node: whether children_ holds its children's
  // A diffuse point's scratch: openWeights of the cut's columns and of the
  // children of the nodes the horizon or a cap cuts.
  std::vector<float> open_, childOpen_, nodeWeight_;
  std::vector<int32_t> flags_, childFlags_;
  std::vector<uint32_t> refined_, refinedEntry_;
  std::vector<CutLight> childLights_;
  CutColumns childColumns_;
  float total_ = 0.0f;
  glm::vec3 colourMean_{0.0f};
};

glm::vec3 estimateHtCut(const Scene& scene, const ShadingPoint& sp, const CutOptions& options, int n, Rng& rng,
                        PixelSampler& sampler, EstimateCounters& counters, const EnvCut& cut, const HtGeometry& g);

}  // namespace ht
