// Hierarchical thresholding (HT): product importance sampling of
// environment x BRDF (x visibility) on the HEALPix hierarchy.
//
// Candidates are base-4 Van der Corput indices on each face's quadtree. A
// node at level l owns the indices r + k 4^l (k = 0, 1, ...), where its lowest
// index r collects the (scrambled) digits of its path: child j of a node gets
// r + perm(j) 4^l, perm one of the 24 permutations of 4 digits, drawn by a
// stateless hash of (pixel seed, level, node). A leaf of value h accepts its
// candidates i with i + u < T(h) = s h A (A = solid angle of a base face,
// u one random offset per pixel), so it receives T / 4^l = s h (leaf solid
// angle) samples on average. A node is pruned when r + u >= T(bound): no
// leaf below it can accept anything. Leaves that call for more than one
// candidate are subdivided virtually (h stays constant) and each accepted
// sample is jittered uniformly inside its cell. The estimate is
// sum f(w) / (s h(w)), with f the exact integrand.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <cstdint>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "brdf_table.h"
#include "huge_buffer.h"
#include "shading.h"
#include "rng.h"
#include "sampler.h"
#include "sampling.h"
#include "scene.h"

namespace ht {

struct MethodTables;  // tables.h

struct HtOptions {
  bool visibility = false;     // multiply by the inner-sphere visibility factor
  bool brdfTable = false;      // BRDF bounds from tabulated trees instead of cones
  bool biased = false;         // stop early where the BRDF is smooth, use its average
  int budgetRefinements = 24;  // node splits used to estimate C = integral of h (< 0: no estimate)
  float brdfFloor = 1e-3f;     // leaf BRDF factor >= brdfFloor * its bound
  float visibilityFloor = 0.1f;  // leaf visibility factor of a partly covered leaf >= this
  int maxLevel = 24;           // deepest (virtual) level; r stays below 12 * 2^48
  // One candidate sequence over the whole sphere (a 12-way top level with
  // its own random permutation) instead of 12 independent face sequences:
  // the faces' counts are then stratified against each other.
  bool sphereSequence = true;
  float biasedSmoothness = 0.25f;  // biased: a node is smooth if BRDF bound <= (1 + this) x centre
};

// Cosine bounds over a cone of radius R (cos R, sin R) around a, towards b:
// cos(max(0, angle(a, b) - R)), the largest cosine, and
// cos(min(pi, angle(a, b) + R)), the smallest.
inline float cosClosest(const glm::vec3& a, const glm::vec3& b, float cosR, float sinR) {
  float c = std::clamp(glm::dot(a, b), -1.0f, 1.0f);
  if (c >= cosR) return 1.0f;
  return c * cosR + std::sqrt(1.0f - c * c) * sinR;
}
inline float cosFarthest(const glm::vec3& a, const glm::vec3& b, float cosR, float sinR) {
  float c = std::clamp(glm::dot(a, b), -1.0f, 1.0f);
  if (c <= -cosR) return -1.0f;
  return c * cosR - std::sqrt(1.0f - c * c) * sinR;
}

// HEALPix geometry shared by every shading point: per node (same layout as
// the max/avg trees) its centre (HEALPix frame) and the cosine and sine of an
// angular radius that bounds it; per level, a radius bounding every node of
// the level (used below the data, for virtual cells, and by visibility caps).
struct HtGeometry {
  int order = 0;
  std::vector<glm::vec3> centers;
  std::vector<glm::vec2> cosSinRadius;
  std::array<float, 32> levelRadius{};
  std::array<float, 32> levelCosRadius{}, levelSinRadius{};
};
std::shared_ptr<const HtGeometry> buildHtGeometry(int order);

// What the CPU traversal reads of one node, packed: the four children of a
// node are 128 contiguous bytes (two cache lines) instead of lines in four
// arrays apart, which is where its time went on deep levels.
struct alignas(32) HtNode {
  glm::vec3 centre;
  float maxv;  // environment tree
  glm::vec2 cosSinRadius;
  float avgv;  // environment tree
  uint32_t hash;  // HtPoint::nodeHash, the pixel-independent part of the node's permutation
};
struct HtNodes {
  uint64_t treeId = 0;  // MaxAvgTree::id of the tree it packs
  size_t count = 0;
  HugeBuffer storage;
  const HtNode* data() const { return static_cast<const HtNode*>(storage.data()); }
};
std::shared_ptr<const HtNodes> buildHtNodes(const HtGeometry& geometry, const MaxAvgTree& tree);

// A spherical cap of blocked directions (sphere occluder or the far side of
// a plane), in the HEALPix frame.
struct Cap {
  glm::vec3 axis;
  float angle;  // half-angle, radians
  float cosAngle;
  // Per level: a node of that level whose centre has cos(centre, axis) >=
  // cosInside lies fully inside; <= cosOutside, fully outside.
  std::array<float, 32> cosInside, cosOutside;
};

// A cap with its inside / outside tests for nodes of `geometry` at levels
// below `levels` (default: the levels the geometry has); deeper levels get
// tests that never decide (every node counts as partly covered).
Cap makeCap(const glm::vec3& axis, float angle, const HtGeometry& geometry, int levels);
inline Cap makeCap(const glm::vec3& axis, float angle, const HtGeometry& geometry) {
  return makeCap(axis, angle, geometry, geometry.order + 1);
}
// The caps a shading point keeps at most, spheres' and planes' (the
// shaders' HT_MAX_CAPS): every plane, and the largest spheres in the rest
// (capSpheres in scene.h). A sphere left out only leaves density where its
// shadow rays return 0, so the estimates stay unbiased.
constexpr size_t kMaxCaps = 16;
// The spheres' share of `caps` slots: what the planes leave.
size_t capSphereCount(const Scene& scene, size_t caps = kMaxCaps);
// Every plane and the spheres of capSpheres as seen from the shading point's
// shadow-ray origin (offsetRayOrigin): a hit point rounded to just below its
// own plane would otherwise see the sky as blocked.
struct Occluder {
  glm::vec3 axis;      // HEALPix frame
  float sinHalfAngle;  // of the cap it blocks; 1 for a plane's far side
};
std::vector<Occluder> occluders(const Scene& scene, const ShadingPoint& sp, size_t caps = kMaxCaps);
// Caps shrink by this (radians) so that "inside" always means blocked.
constexpr float kCapMargin = 1e-3f;
// The caps of every occluder.
std::vector<Cap> visibilityCaps(const Scene& scene, const ShadingPoint& sp, const HtGeometry& geometry, int levels);
inline std::vector<Cap> visibilityCaps(const Scene& scene, const ShadingPoint& sp, const HtGeometry& geometry) {
  return visibilityCaps(scene, sp, geometry, geometry.order + 1);
}

struct HtSample {
  glm::vec3 dir;       // world space
  uint64_t pixel;      // environment pixel (leaf) holding the sample
  uint64_t candidate;  // the accepted VDC index within its face
  int face;
  int level;           // level of the cell it was jittered in
  float h;             // acceptance value of the leaf
  float weight;        // 1 / (s h)
  bool averaged;       // biased: use the BRDF at `brdfDir` instead of at `dir`
  glm::vec3 brdfDir;   // HEALPix frame: centre of the smooth node
};

struct HtCounters {
  uint64_t nodes = 0;    // nodes visited (bounds evaluated)
  uint64_t samples = 0;  // accepted candidates
};

// Everything HT needs at one shading point.
class HtPoint {
 public:
  // `tables`: the geometry of the map's order, and the material's BRDF
  // table with options.brdfTable.
  HtPoint(const Scene& scene, const ShadingPoint& sp, const HtOptions& options, const MethodTables& tables);
  HtPoint(const Scene&, const ShadingPoint&, const HtOptions&, MethodTables&&) = delete;  // keeps references into it

  // Sets the expected sample count n: s = n / C_est.
  void setBudget(double n);
  double budgetEstimate() const { return cEst_; }
  double scale() const { return s_; }
  // T(h) = s h A, A the measure one candidate sequence covers.
  double threshold(float h) const { return s_ * double(h) * sequenceArea_; }
  // Candidates of a level-l node are r + k * stride(l).
  uint64_t stride(int level) const { return sequenceRoots_ << (2 * level); }

  // Upper bound of the product over a node (level <= environment order).
  float bound(int level, uint64_t node) const;
  // Acceptance value of a leaf given the smallest bound on its path.
  float leafValue(uint64_t leaf, float pathBound) const;
  // Smallest bound over the path from the face root to `leaf` (inclusive).
  float pathBound(uint64_t leaf) const;

  // Runs the traversal, appending the accepted samples to `out`.
  void traverse(uint32_t pixelSeed, float u, PixelSampler& jitter, std::vector<HtSample>& out, HtCounters& counters) const;

  // Lowest candidate index of a node, from the digit permutations on its path.
  uint64_t lowestCandidate(uint32_t pixelSeed, int level, uint64_t node) const;
  // The digit of a face in the whole-sphere sequence (0 for face sequences).
  uint64_t faceDigit(uint32_t pixelSeed, int face) const;
  std::array<uint8_t, 12> faceDigits(uint32_t pixelSeed) const;
  static int digit(uint32_t pixelSeed, int level, uint64_t node, int child);
  // The digits a node gives its children: one of the 24 permutations, drawn
  // by a hash of the pixel seed and nodeHash, the part no pixel changes.
  static const std::array<uint8_t, 4>& permutation(uint32_t pixelSeed, int level, uint64_t node);
  static const std::array<uint8_t, 4>& permutationOf(uint32_t pixelSeed, uint32_t nodeHash);
  static uint32_t nodeHash(int level, uint64_t node);

  static constexpr double kFaceSolidAngle = 4.0 * 3.14159265358979323846 / 12.0;

  const Scene& scene;
  const Environment& env;
  const HtOptions options;
  const HtGeometry& geometry;
  const Material& material;
  Frame frame;        // shading frame in the HEALPix frame
  glm::vec3 woLocal;  // in the shading frame
  glm::vec3 n, wo, mirror;  // HEALPix frame
  float brdfG1 = 1.0f;
  std::vector<Cap> caps;
  const HtNode* nodes;               // HtNodes of the map's tree
  const BrdfTable* table = nullptr;  // tabulated bounds, when chosen
  glm::vec3 tableX, tableY;          // tangents of the table's frame (wo in its x-z plane)
  float thetaO = 0.0f;

  // Bound over node i (index into the flat per-level layout).
  float brdfBound(uint64_t i) const;
  // The same, with the diffuse lobe's share of it in `diffuse` (all of it
  // with tabulated bounds).
  float brdfBound(uint64_t i, float& diffuse) const;
  float brdfValue(const glm::vec3& dirHp) const;
  glm::vec3 brdfColour(const glm::vec3& dirHp) const;  // f cos in colour (no table)
  // 0: the cone is fully blocked, 1: fully free, 2: partly covered.
  int visibilityClass(const glm::vec3& axis, int level) const;
  float visibleFraction(uint64_t leaf) const;
  float nodeEstimate(int level, uint64_t node) const;
  // The same with the node's BRDF bound and visibility class known.
  float nodeEstimate(int level, uint64_t node, float brdfBound, int visibility) const;

 private:
  struct Walk;
  void visit(Walk& w, int level, uint64_t node, uint64_t r, float pathMin, int32_t known) const;
  // bound(), also giving its BRDF bound and visibility class.
  float bound(int level, uint64_t node, float& brdfBound, int& visibility) const;
  // leafValue with the leaf's BRDF bound and visibility class known.
  float leafValue(uint64_t leaf, float pathBound, float brdfBound, int visibility) const;
  void visitVirtual(Walk& w, int level, uint64_t vnode, uint64_t r, float h, uint64_t leaf, uint64_t sx, uint64_t sy) const;
  bool stopEarly(Walk& w, int level, uint64_t node, uint64_t r, float pathMin, float brdfBound, int visibility) const;
  void estimateBudget();

  // The budget's frontier and the nodes it split, with the BRDF bound and
  // visibility class of each: the traversal takes them instead of
  // computing them again. child[j]: index of child j, -1 where not kept
  // or not split.
  struct BudgetNode {
    int level;
    uint64_t node;
    bool split;
    float brdfBound;
    int visibility;
    std::array<int32_t, 4> child;
  };
  std::vector<BudgetNode> budget_;
  std::array<int32_t, 12> budgetFace_{-1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1};
  double cEst_ = 1.0;
  double s_ = 0.0;
  // One candidate sequence covers 12 faces or one.
  double sequenceArea_ = kFaceSolidAngle;
  uint64_t sequenceRoots_ = 1;
  struct BoundTerms {
    float diffuse, phong;                 // luminance x normalisation of the Lambert and Phong lobes
    float a2, a2Minus1, f0, oneMinusF0;  // GGX
    float fourCosO;
  } boundTerms_{};
  // Up to eight caps as two groups of four lanes, for visibilityClass to
  // test a group at once: lane k of group g is cap 4g + k; padding lanes
  // (axis 0, thresholds 2) never decide. More caps take the plain loop.
  static constexpr int kCapLanes = 8;
  struct CapLanes {
    int groups = 0;  // 0: the plain loop
    alignas(16) std::array<float, kCapLanes> x, y, z;
    alignas(16) std::array<std::array<float, kCapLanes>, 32> inside, outside;
  } capLanes_;
  void buildCapLanes();
};

// HT estimate at a shading point with n expected samples (the `ht*` methods):
// candidates from pixelSeed and one draw of rng, each accepted sample's
// point inside its cell from the sampler.
glm::vec3 estimateHt(const Scene& scene, const ShadingPoint& sp, const HtOptions& options, int n,
                     uint32_t pixelSeed, Rng& rng, PixelSampler& sampler, EstimateCounters& counters,
                     const MethodTables& tables);

}  // namespace ht
