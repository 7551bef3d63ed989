#include "ht.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <memory>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include <glm/geometric.hpp>
#include <tbb/parallel_for.h>

#include "bsdf.h"
#include "error.h"
#include "healpix.h"
#include "tables.h"
#include "tree.h"

namespace ht {
namespace {

// The 24 permutations of {0, 1, 2, 3}.
constexpr std::array<std::array<uint8_t, 4>, 24> kPermutations = [] {
  std::array<std::array<uint8_t, 4>, 24> p{};
  int n = 0;
  for (uint8_t a = 0; a < 4; ++a)
    for (uint8_t b = 0; b < 4; ++b)
      for (uint8_t c = 0; c < 4; ++c)
        for (uint8_t d = 0; d < 4; ++d)
          if (a != b && a != c && a != d && b != c && b != d && c != d) p[n++] = {a, b, c, d};
  return p;
}();

// Largest angle from a pixel's centre c to its corners, with the margin that
// covers edges bulging past the corner-to-corner span and rounding.
double cornerRadius(int level, uint64_t pix, const glm::dvec3& c) {
  double r = 0.0;
  for (int k = 0; k < 4; ++k) {
    glm::dvec3 q = healpix::pixToVec(level, pix, double(k & 1), double(k >> 1));
    r = std::max(r, std::atan2(glm::length(glm::cross(c, q)), glm::dot(c, q)));
  }
  return r * (1.0 + 1e-3) + 1e-6;
}

constexpr int kExactRadiusLevels = 8;  // beyond: scaled from this level with a margin

std::unique_ptr<HtGeometry> buildGeometry(int order) {
  auto g = std::make_unique<HtGeometry>();
  g->order = order;
  g->centers.resize(MaxAvgTree::levelOffset(order + 1));
  g->cosSinRadius.resize(g->centers.size());
  // The radii of a level that sets its levelRadius (at most 12 x 4^8).
  std::vector<double> radius;
  for (int l = 0; l <= std::max(order, std::min(kExactRadiusLevels, healpix::kMaxOrder)); ++l) {
    const uint64_t offset = MaxAvgTree::levelOffset(l);
    const bool exact = l <= kExactRadiusLevels, stored = l <= order;
    radius.assign(exact ? MaxAvgTree::levelSize(l) : 0, 0.0);
    tbb::parallel_for(uint64_t(0), MaxAvgTree::levelSize(l), [&](uint64_t p) {
      const glm::dvec3 c = healpix::pixToVec(l, p);
      const double r = cornerRadius(l, p, c);
      if (exact) radius[p] = r;
      if (!stored) return;
      g->centers[offset + p] = glm::vec3(c);
      g->cosSinRadius[offset + p] = glm::vec2(float(std::cos(r)), float(std::sin(r)));
    });
    if (exact) g->levelRadius[l] = float(*std::max_element(radius.begin(), radius.end()));
  }
  // Pixels halve at each finer level and grow more regular: scale the last
  // exact radius, with 5% to spare (checked against every level in tests).
  for (int l = kExactRadiusLevels + 1; l < int(g->levelRadius.size()); ++l)
    g->levelRadius[l] = float(g->levelRadius[kExactRadiusLevels] * std::ldexp(1.05, kExactRadiusLevels - l));
  for (size_t l = 0; l < g->levelRadius.size(); ++l) {
    g->levelCosRadius[l] = std::cos(g->levelRadius[l]);
    g->levelSinRadius[l] = std::sin(g->levelRadius[l]);
  }
  return g;
}

glm::vec3 toFloat(const glm::dvec3& v) { return glm::vec3(v); }

// healpix::pixelSolidAngle per level, without a division per node.
constexpr std::array<double, healpix::kMaxOrder + 1> kPixelSolidAngle = [] {
  std::array<double, healpix::kMaxOrder + 1> a{};
  for (int l = 0; l <= healpix::kMaxOrder; ++l) a[l] = healpix::pixelSolidAngle(l);
  return a;
}();

}  // namespace

std::shared_ptr<const HtGeometry> buildHtGeometry(int order) { return buildGeometry(order); }

std::shared_ptr<const HtNodes> buildHtNodes(const HtGeometry& g, const MaxAvgTree& tree) {
  const size_t n = g.centers.size();
  if (tree.order != g.order || tree.maxv.size() != n || tree.avgv.size() != n)
    throw Error("internal: HT node records of a tree and a geometry of different orders");
  auto out = std::make_shared<HtNodes>();
  out->treeId = tree.id;
  out->count = n;
  out->storage = HugeBuffer(n * sizeof(HtNode));
  HtNode* nodes = static_cast<HtNode*>(out->storage.data());
  for (int l = 0; l <= g.order; ++l) {
    const uint64_t offset = MaxAvgTree::levelOffset(l);
    tbb::parallel_for(uint64_t(0), MaxAvgTree::levelSize(l), [&](uint64_t p) {
      const size_t i = offset + p;
      std::construct_at(nodes + i, HtNode{g.centers[i], tree.maxv[i], g.cosSinRadius[i], tree.avgv[i],
                                          HtPoint::nodeHash(l, p)});
    });
  }
  return out;
}

Cap makeCap(const glm::vec3& axis, float angle, const HtGeometry& geometry, int levels) {
  Cap c{axis, angle, std::cos(angle), {}, {}};
  c.cosInside.fill(2.0f);    // never inside
  c.cosOutside.fill(-2.0f);  // never outside
  for (int l = 0; l < std::min(levels, int(c.cosInside.size())); ++l) {
    float rad = geometry.levelRadius[l];
    c.cosInside[l] = angle > rad ? std::cos(angle - rad) : 2.0f;
    c.cosOutside[l] = std::cos(std::min(kPi, angle + rad));
  }
  return c;
}

size_t capSphereCount(const Scene& scene, size_t caps) { return caps - std::min(caps, scene.planes.size()); }

std::vector<Occluder> occluders(const Scene& scene, const ShadingPoint& sp, size_t caps) {
  const Environment& env = scene.environment;
  std::vector<Occluder> out;
  out.reserve(std::max(caps, scene.planes.size()));
  const glm::vec3 origin = offsetRayOrigin(sp.position, sp.normal);
  for (const uint32_t i : capSpheres(scene, origin, sp.normal, capSphereCount(scene, caps))) {
    const Sphere& s = scene.spheres[i];
    const glm::vec3 d = s.center - origin;
    const float dist = glm::length(d);
    if (!(dist > 0.0f)) continue;
    out.push_back({glm::normalize(toFloat(env.toHealpixFrame(d / dist))), std::min(1.0f, s.radius / dist)});
  }
  for (const Plane& p : scene.planes) {
    const glm::vec3 below = glm::dot(origin - p.point, p.normal) >= 0.0f ? -p.normal : p.normal;
    out.push_back({glm::normalize(toFloat(env.toHealpixFrame(below))), 1.0f});
  }
  return out;
}

std::vector<Cap> visibilityCaps(const Scene& scene, const ShadingPoint& sp, const HtGeometry& geometry, int levels) {
  const std::vector<Occluder> blockers = occluders(scene, sp);
  std::vector<Cap> caps;
  caps.reserve(blockers.size());
  for (const Occluder& o : blockers) {
    // A plane's far side: pi/2 exactly as the shaders' kHtPlaneCapAngle.
    const float angle = (o.sinHalfAngle == 1.0f ? 0.5f * kPi : std::asin(o.sinHalfAngle)) - kCapMargin;
    if (angle > 0.0f) caps.push_back(makeCap(o.axis, angle, geometry, levels));
  }
  return caps;
}

HtPoint::HtPoint(const Scene& sc, const ShadingPoint& sp, const HtOptions& opt, const MethodTables& tables)
    : scene(sc),
      env(sc.environment),
      options(opt),
      geometry(tables.geometry()),
      material(*sp.material),
      frame(glm::normalize(toFloat(sc.environment.toHealpixFrame(sp.normal)))),
      nodes(tables.nodes().data()) {
  if (tables.nodes().treeId != env.tree.id || geometry.order != env.order)
    throw Error("internal: HT tables prepared for another environment");
  if (options.sphereSequence) {
    sequenceArea_ = 12.0 * kFaceSolidAngle;
    sequenceRoots_ = 12;
  }
  n = frame.n;
  wo = glm::normalize(toFloat(env.toHealpixFrame(sp.wo)));
  woLocal = frame.toLocal(wo);
  mirror = reflectAbout(wo, n);
  if (material.type == MaterialType::Ggx) brdfG1 = ggxG1(woLocal, material.alpha);
  // brdfBound's factors that hold for every node, each computed as its
  // expression there groups them (the same values).
  boundTerms_.diffuse = luminance(material.diffuse) * kInvPi;
  boundTerms_.phong = luminance(material.specular) * (material.exponent + 2.0f) * 0.5f * kInvPi;
  boundTerms_.a2 = material.alpha * material.alpha;
  boundTerms_.a2Minus1 = boundTerms_.a2 - 1.0f;
  boundTerms_.f0 = luminance(material.specular);
  boundTerms_.oneMinusF0 = 1.0f - boundTerms_.f0;
  boundTerms_.fourCosO = 4.0f * woLocal.z;
  if (options.brdfTable) {
    table = &tables.own<BrdfTables>().at(size_t(sp.material - sc.materials.data()));
    thetaO = std::acos(std::clamp(woLocal.z, -1.0f, 1.0f));
    glm::vec3 tangent = wo - glm::dot(wo, n) * n;
    tableX = glm::length(tangent) > 1e-6f ? glm::normalize(tangent) : frame.s;
    tableY = glm::cross(n, tableX);
  }
  if (options.visibility) {
    caps = visibilityCaps(scene, sp, geometry);
    buildCapLanes();
  }
  if (options.budgetRefinements >= 0) estimateBudget();
}

glm::vec3 HtPoint::brdfColour(const glm::vec3& dirHp) const {
  return evalBsdf(material, woLocal, frame.toLocal(dirHp));
}

float HtPoint::brdfValue(const glm::vec3& dirHp) const {
  if (table) return table->average(thetaO, {glm::dot(dirHp, tableX), glm::dot(dirHp, tableY), glm::dot(dirHp, n)});
  if (material.type == MaterialType::Lambert) {  // evalBsdf's value, from the cosine alone
    const float cosI = glm::dot(dirHp, frame.n);
    return woLocal.z <= 0.0f || cosI <= 0.0f ? 0.0f : luminance(diffuseFcos(material, cosI));
  }
  return luminance(brdfColour(dirHp));
}

// Bound of luminance(f cos) over a node's cone: each lobe bounded by its
// value at the smallest angle the cone allows (DESIGN.md section 6), in
// cosines so that no inverse trigonometry is needed.
float HtPoint::brdfBound(uint64_t i) const {
  if (material.type == MaterialType::Lambert && !table) {  // the lobe most points have, inline
    const HtNode& nd = nodes[i];
    const float cosMax = cosClosest(nd.centre, n, nd.cosSinRadius.x, nd.cosSinRadius.y);
    return cosMax <= 0.0f || woLocal.z <= 0.0f ? 0.0f : boundTerms_.diffuse * cosMax;
  }
  float diffuse;
  return brdfBound(i, diffuse);
}

float HtPoint::brdfBound(uint64_t i, float& diffuse) const {
  const HtNode& nd = nodes[i];
  const glm::vec3& axis = nd.centre;
  const float cr = nd.cosSinRadius.x, sr = nd.cosSinRadius.y;
  if (table) {
    diffuse = table->bound(thetaO, {glm::dot(axis, tableX), glm::dot(axis, tableY), glm::dot(axis, n)}, cr, sr);
    return diffuse;
  }
  diffuse = 0.0f;
  float cosMax = cosClosest(axis, n, cr, sr);
  if (cosMax <= 0.0f || woLocal.z <= 0.0f) return 0.0f;
  const BoundTerms& k = boundTerms_;
  float b = k.diffuse * cosMax;
  diffuse = b;
  if (material.type == MaterialType::Phong) {
    float c = cosClosest(axis, mirror, cr, sr);
    if (c > 0.0f) b += k.phong * std::pow(c, material.exponent) * cosMax;
  } else if (material.type == MaterialType::Ggx) {
    // Rotating wo about h and about n differ by a rotation of twice their
    // angle, so angle(h, n) >= angle(w, mirror) / 2.
    float cos2H = 0.5f * (1.0f + cosClosest(axis, mirror, cr, sr));
    float d = cos2H * k.a2Minus1 + 1.0f;
    float dMax = k.a2 / (kPi * d * d);
    // Schlick grows with the half angle between wo and w.
    float cosHalf = std::sqrt(std::max(0.0f, 0.5f * (1.0f + cosFarthest(axis, wo, cr, sr))));
    float m = 1.0f - cosHalf;
    float fresnel = k.f0 + k.oneMinusF0 * m * m * m * m * m;
    b += fresnel * dMax * brdfG1 / k.fourCosO;
  }
  return b;
}

void HtPoint::buildCapLanes() {
  CapLanes& c = capLanes_;
  c.groups = 0;
#if defined(__SSE2__)
  if (caps.size() > size_t(kCapLanes)) return;
  c.groups = int(caps.size() + 3) / 4;
  c.x.fill(0.0f), c.y.fill(0.0f), c.z.fill(0.0f);
  for (int l = 0; l <= geometry.order; ++l) c.inside[l].fill(2.0f), c.outside[l].fill(2.0f);
  for (size_t k = 0; k < caps.size(); ++k) {
    c.x[k] = caps[k].axis.x, c.y[k] = caps[k].axis.y, c.z[k] = caps[k].axis.z;
    for (int l = 0; l <= geometry.order; ++l) {
      c.inside[l][k] = caps[k].cosInside[l];
      c.outside[l][k] = caps[k].cosOutside[l];
    }
  }
#endif
}

// Which cap holds the cone does not matter, so four are tested at once
// where the vector unit allows: the same dot products, lane by lane, as
// glm::dot's ((x + y) + z).
int HtPoint::visibilityClass(const glm::vec3& axis, int level) const {
#if defined(__SSE2__)
  const CapLanes& c = capLanes_;
  if (c.groups > 0 && level <= geometry.order) {
    const __m128 x = _mm_set1_ps(axis.x), y = _mm_set1_ps(axis.y), z = _mm_set1_ps(axis.z);
    const auto dot = [&](int g) {
      const __m128 xy = _mm_add_ps(_mm_mul_ps(x, _mm_load_ps(&c.x[4 * g])), _mm_mul_ps(y, _mm_load_ps(&c.y[4 * g])));
      return _mm_add_ps(xy, _mm_mul_ps(z, _mm_load_ps(&c.z[4 * g])));
    };
    const float* inside = c.inside[level].data();
    const float* outside = c.outside[level].data();
    const __m128 d0 = dot(0);
    __m128 in = _mm_cmpge_ps(d0, _mm_load_ps(inside));
    __m128 partial = _mm_cmpgt_ps(d0, _mm_load_ps(outside));
    if (c.groups > 1) {
      const __m128 d1 = dot(1);
      in = _mm_or_ps(in, _mm_cmpge_ps(d1, _mm_load_ps(inside + 4)));
      partial = _mm_or_ps(partial, _mm_cmpgt_ps(d1, _mm_load_ps(outside + 4)));
    }
    if (_mm_movemask_ps(in) != 0) return 0;
    return _mm_movemask_ps(partial) != 0 ? 2 : 1;
  }
#endif
  bool partial = false;
  for (const Cap& c : caps) {
    float d = glm::dot(axis, c.axis);
    if (d >= c.cosInside[level]) return 0;
    if (d > c.cosOutside[level]) partial = true;
  }
  return partial ? 2 : 1;
}

float HtPoint::visibleFraction(uint64_t leaf) const {
  static constexpr float kOffsets[5][2] = {{0.5f, 0.5f}, {0.25f, 0.25f}, {0.75f, 0.25f}, {0.25f, 0.75f}, {0.75f, 0.75f}};
  int free = 0;
  for (const auto& o : kOffsets) {
    glm::vec3 d = toFloat(healpix::pixToVec(env.order, leaf, o[0], o[1]));
    bool blocked = false;
    for (const Cap& c : caps) blocked |= glm::dot(d, c.axis) > c.cosAngle;
    free += !blocked;
  }
  return std::max(options.visibilityFloor, float(free) / 5.0f);
}

float HtPoint::bound(int level, uint64_t node) const {
  float brdfB;
  int cls;
  return bound(level, node, brdfB, cls);
}

float HtPoint::bound(int level, uint64_t node, float& brdfB, int& cls) const {
  const uint64_t i = MaxAvgTree::levelOffset(level) + node;
  brdfB = 0.0f;
  cls = 1;
  float e = nodes[i].maxv;
  if (e <= 0.0f) return 0.0f;
  brdfB = brdfBound(i);
  float b = e * brdfB;
  if (b > 0.0f && options.visibility) {
    cls = visibilityClass(nodes[i].centre, level);
    if (cls == 0) return 0.0f;
  }
  return b;
}

// Product of the factors' averages per unit solid angle, each never below a
// floor of its own bound, so that it is positive wherever the bound is.
float HtPoint::nodeEstimate(int level, uint64_t node) const {
  const uint64_t i = MaxAvgTree::levelOffset(level) + node;
  return nodeEstimate(level, node, brdfBound(i), options.visibility ? visibilityClass(nodes[i].centre, level) : 1);
}

float HtPoint::nodeEstimate(int level, uint64_t node, float brdfB, int cls) const {
  const uint64_t i = MaxAvgTree::levelOffset(level) + node;
  float brdf = std::max(brdfValue(nodes[i].centre), options.brdfFloor * brdfB);
  float vis = cls == 0 ? 0.0f : cls == 1 ? 1.0f : 0.5f;
  return nodes[i].avgv * brdf * vis;
}

float HtPoint::leafValue(uint64_t leaf, float pathMin) const {
  const uint64_t i = MaxAvgTree::levelOffset(env.order) + leaf;
  return leafValue(leaf, pathMin, brdfBound(i), options.visibility ? visibilityClass(nodes[i].centre, env.order) : 1);
}

float HtPoint::leafValue(uint64_t leaf, float pathMin, float brdfB, int cls) const {
  const uint64_t i = MaxAvgTree::levelOffset(env.order) + leaf;
  float e = nodes[i].avgv;
  if (e <= 0.0f || pathMin <= 0.0f) return 0.0f;
  if (brdfB <= 0.0f || cls == 0) return 0.0f;
  float h = e * std::max(brdfValue(nodes[i].centre), options.brdfFloor * brdfB);
  if (cls == 2) h *= visibleFraction(leaf);
  // Never above a bound used to prune an ancestor: pruning then loses nothing.
  return std::min(h, pathMin);
}

float HtPoint::pathBound(uint64_t leaf) const {
  float m = INFINITY;
  for (int l = env.order; l >= 0; --l) m = std::min(m, bound(l, leaf >> (2 * (env.order - l))));
  return m;
}

uint32_t HtPoint::nodeHash(int level, uint64_t node) {
  constexpr uint32_t kHashOfZero = pcgHash(0u);  // the high word of every data node
  const uint32_t high = uint32_t(node >> 32);
  const uint32_t highHash = high == 0u ? kHashOfZero : pcgHash(high);
  return pcgHash(uint32_t(level) ^ pcgHash(uint32_t(node) ^ highHash));
}

const std::array<uint8_t, 4>& HtPoint::permutationOf(uint32_t pixelSeed, uint32_t nodeHash) {
  return kPermutations[pcgHash(pixelSeed ^ nodeHash) % 24];
}

const std::array<uint8_t, 4>& HtPoint::permutation(uint32_t pixelSeed, int level, uint64_t node) {
  return permutationOf(pixelSeed, nodeHash(level, node));
}

int HtPoint::digit(uint32_t pixelSeed, int level, uint64_t node, int child) {
  return permutation(pixelSeed, level, node)[child];
}

std::array<uint8_t, 12> HtPoint::faceDigits(uint32_t pixelSeed) const {
  std::array<uint8_t, 12> perm{};
  if (!options.sphereSequence) return perm;
  // Fisher-Yates shuffle of the 12 faces, drawn from the pixel seed.
  for (int i = 0; i < 12; ++i) perm[i] = uint8_t(i);
  uint32_t h = pcgHash(pixelSeed ^ 0x9e3779b9u);
  for (int i = 11; i > 0; --i) {
    h = pcgHash(h);
    std::swap(perm[i], perm[h % uint32_t(i + 1)]);
  }
  return perm;
}

uint64_t HtPoint::faceDigit(uint32_t pixelSeed, int face) const { return faceDigits(pixelSeed)[face]; }

uint64_t HtPoint::lowestCandidate(uint32_t pixelSeed, int level, uint64_t node) const {
  // Digits of the path from the face root (level 0) down to `node`.
  uint64_t r = faceDigit(pixelSeed, int(node >> (2 * level)));
  for (int l = 0; l < level; ++l) {
    uint64_t ancestor = node >> (2 * (level - l));
    int child = int((node >> (2 * (level - l - 1))) & 3);
    r += uint64_t(digit(pixelSeed, l, ancestor, child)) * stride(l);
  }
  return r;
}

void HtPoint::estimateBudget() {
  // Refine the nodes with the largest bound mass, then sum the estimates of
  // the frontier: C_est ~ integral of h. A wrong C_est changes the expected
  // sample count, never the expectation of the estimate. The largest mass
  // comes from a heap; ties go to the node inserted first, and the sum runs
  // in insertion order, as the GPU's linear scan does.
  struct Entry {
    double mass;
    int32_t index;  // into nodes
  };
  // The heap's order: the larger mass first, then the smaller index.
  const auto before = [](const Entry& a, const Entry& b) {
    return (a.mass < b.mass) | ((a.mass == b.mass) & (a.index > b.index));  // no branch of its own
  };
  thread_local std::vector<Entry> heap;
  std::vector<BudgetNode>& nodes = budget_;
  nodes.clear();
  nodes.reserve(12 + 4 * size_t(std::max(0, options.budgetRefinements)));
  heap.clear();
  auto push = [&](int l, uint64_t p) -> int32_t {
    float brdfB;
    int cls;
    double mass = double(bound(l, p, brdfB, cls)) * kPixelSolidAngle[l];
    if (!(mass > 0.0)) return -1;
    heap.push_back({mass, int32_t(nodes.size())});
    std::push_heap(heap.begin(), heap.end(), before);
    nodes.push_back({l, p, false, brdfB, cls, {-1, -1, -1, -1}});
    return int32_t(nodes.size() - 1);
  };
  for (int f = 0; f < 12; ++f) budgetFace_[f] = push(0, uint64_t(f));
  for (int k = 0; k < options.budgetRefinements && !heap.empty(); ++k) {
    const size_t top = size_t(heap.front().index);
    if (nodes[top].level >= env.order) break;
    std::pop_heap(heap.begin(), heap.end(), before);
    heap.pop_back();
    nodes[top].split = true;
    const int level = nodes[top].level + 1;
    const uint64_t first = 4 * nodes[top].node;
    for (int j = 0; j < 4; ++j) {
      const int32_t child = push(level, first + uint64_t(j));
      nodes[top].child[j] = child;
    }
  }
  double c = 0.0;
  for (const BudgetNode& nd : nodes)
    if (!nd.split)
      c += double(nodeEstimate(nd.level, nd.node, nd.brdfBound, nd.visibility)) * kPixelSolidAngle[nd.level];
  cEst_ = c;
}

void HtPoint::setBudget(double expected) { s_ = cEst_ > 0.0 ? expected / cEst_ : 0.0; }

struct HtPoint::Walk {
  uint32_t seed;
  double u;
  int face;
  PixelSampler& jitter;  // sample k's point inside its cell: sample index k, dimension 0
  std::vector<HtSample>& out;
  HtCounters& counters;
};

void HtPoint::traverse(uint32_t pixelSeed, float u, PixelSampler& jitter, std::vector<HtSample>& out,
                       HtCounters& counters) const {
  if (s_ <= 0.0) return;
  const std::array<uint8_t, 12> digits = faceDigits(pixelSeed);
  for (int f = 0; f < 12; ++f) {
    Walk w{pixelSeed, double(u), f, jitter, out, counters};
    visit(w, 0, uint64_t(f), digits[f], INFINITY, budgetFace_[f]);
  }
}

void HtPoint::visit(Walk& w, int level, uint64_t node, uint64_t r, float pathMin, int32_t known) const {
  ++w.counters.nodes;
  // bound(level, node), with the caps tested only where the cone's bound
  // alone does not prune: a blocked node's bound is 0 and prunes too. The
  // budget's nodes (`known`) keep the factors it computed.
  const uint64_t i = MaxAvgTree::levelOffset(level) + node;
  if (level < env.order) {
    // The children's two lines load while this node is bounded.
    const HtNode* children = nodes + MaxAvgTree::levelOffset(level + 1) + 4 * node;
    __builtin_prefetch(children);
    __builtin_prefetch(children + 2);
  }
  const BudgetNode* kn = known >= 0 ? &budget_[size_t(known)] : nullptr;
  const float e = nodes[i].maxv;
  const float brdfB = kn ? kn->brdfBound : e > 0.0f ? brdfBound(i) : 0.0f;
  float b = e > 0.0f ? e * brdfB : 0.0f;
  const double ru = double(r) + w.u;
  if (ru >= threshold(b)) return;
  if (level + 1 < env.order) {
    const HtNode* grand = nodes + MaxAvgTree::levelOffset(level + 2) + 16 * node;
    for (int k = 0; k < 16; k += 2) __builtin_prefetch(grand + k);
  }
  int cls = 1;
  if (kn) {
    cls = kn->visibility;
  } else if (options.visibility) {
    cls = visibilityClass(nodes[i].centre, level);
    if (cls == 0) return;
  }
  pathMin = std::min(pathMin, b);
  if (options.biased && stopEarly(w, level, node, r, pathMin, brdfB, cls)) return;
  if (level == env.order) {
    float h = leafValue(node, pathMin, brdfB, cls);
    if (h > 0.0f) visitVirtual(w, level, node, r, h, node, 0, 0);
    return;
  }
  // Every leaf below has h <= pathMin and every candidate below is >= the
  // child's lowest one: a child whose lowest candidate misses T(pathMin)
  // accepts nothing, and its bound need not be computed.
  const double tPath = threshold(pathMin);
  const auto& perm = permutationOf(w.seed, nodes[i].hash);
  const uint64_t step = stride(level);
  const double u = w.u;
  // Which children pass, without a branch per child: the walk's branches
  // are hard to predict, and a missed one costs more than the tests.
  std::array<uint64_t, 4> rc;
  unsigned pass = 0;
  for (int j = 0; j < 4; ++j) {
    rc[j] = r + perm[j] * step;
    pass |= unsigned(double(rc[j]) + u < tPath) << j;
  }
  for (; pass != 0; pass &= pass - 1) {
    const int j = std::countr_zero(pass);
    visit(w, level + 1, 4 * node + j, rc[j], pathMin, kn ? kn->child[j] : -1);
  }
}

// Biased variant: where the BRDF hardly varies over a node and the node
// holds a single acceptable candidate, accept it there with the node's
// average as h and the BRDF at the node's centre as its value. The error is
// bounded by the smoothness threshold; with more samples per pixel, nodes
// hold more candidates, the traversal goes deeper and the contributions
// blend back to exact ones.
bool HtPoint::stopEarly(Walk& w, int level, uint64_t node, uint64_t r, float pathMin, float brdfB, int cls) const {
  const uint64_t i = MaxAvgTree::levelOffset(level) + node;
  const glm::vec3& c = nodes[i].centre;
  float centre = brdfValue(c);
  // Smooth where the BRDF's maximum over the node is close to its centre
  // value; the tables' maxima carry a margin that is not the BRDF's.
  const float margin = options.brdfTable ? BrdfTable::kMargin : 1.0f;
  if (!(centre > 0.0f) || brdfB > (1.0f + options.biasedSmoothness) * centre * margin) return false;
  // The environment keeps its exact value; a node where it varies a lot
  // would turn that into fireflies.
  if (nodes[i].maxv > 2.0f * nodes[i].avgv) return false;
  if (cls != 1) return false;
  float h = std::min(pathMin, nodes[i].avgv * centre);
  if (!(h > 0.0f)) return false;
  const double t = threshold(h);
  if (double(r) + w.u >= t) return true;
  if (double(r) + double(stride(level)) + w.u < t) return false;
  HtSample s;
  w.jitter.startSample(uint32_t(w.counters.samples));
  const glm::vec2 jitter = w.jitter.get2D();
  glm::dvec3 hp = healpix::pixToVec(level, node, jitter.x, jitter.y);
  s.dir = env.fromHealpixFrame(hp);
  s.pixel = healpix::vecToPix(env.order, hp);
  s.candidate = r;
  s.face = w.face;
  s.level = level;
  s.h = h;
  s.weight = float(1.0 / (s_ * double(h)));
  s.averaged = true;
  s.brdfDir = c;
  w.out.push_back(s);
  ++w.counters.samples;
  return true;
}

// Cells at and below the data leaf, where h is constant. (sx, sy) locate the
// cell inside the leaf pixel on a 2^(level - order) grid.
void HtPoint::visitVirtual(Walk& w, int level, uint64_t vnode, uint64_t r, float h, uint64_t leaf, uint64_t sx,
                           uint64_t sy) const {
  const double t = threshold(h);
  if (double(r) + w.u >= t) return;
  const double step = double(stride(level));
  if (double(r) + step + w.u < t && level < options.maxLevel) {
    const auto& perm = permutation(w.seed, level, vnode);
    for (int j = 0; j < 4; ++j)
      visitVirtual(w, level + 1, 4 * vnode + j, r + perm[j] * stride(level), h, leaf, 2 * sx + (j & 1),
                   2 * sy + (j >> 1));
    return;
  }
  // One candidate (or, at the deepest level, all that remain), each uniform in the cell.
  const double cells = double(uint64_t(1) << (level - env.order));
  for (double i = double(r); i + w.u < t; i += step) {
    w.jitter.startSample(uint32_t(w.counters.samples));
    const glm::vec2 jitter = w.jitter.get2D();
    double dx = (double(sx) + jitter.x) / cells;
    double dy = (double(sy) + jitter.y) / cells;
    HtSample s;
    s.dir = env.fromHealpixFrame(healpix::pixToVec(env.order, leaf, dx, dy));
    s.pixel = leaf;
    s.candidate = uint64_t(i);
    s.face = w.face;
    s.level = level;
    s.h = h;
    s.weight = float(1.0 / (s_ * double(h)));
    s.averaged = false;
    w.out.push_back(s);
    ++w.counters.samples;
  }
}

glm::vec3 estimateHt(const Scene& scene, const ShadingPoint& sp, const HtOptions& options, int n, uint32_t pixelSeed,
                     Rng& rng, PixelSampler& sampler, EstimateCounters& counters, const MethodTables& tables) {
  if (!scene.environment.hasLight()) return glm::vec3(0.0f);
  HtPoint ht(scene, sp, options, tables);
  ht.setBudget(double(n));
  thread_local std::vector<HtSample> samples;
  samples.clear();
  HtCounters hc;
  float u = rng.next();
  ht.traverse(pixelSeed, u, sampler, samples, hc);

  const Frame shading(sp.normal);
  const glm::vec3 woLocal = shading.toLocal(sp.wo);
  const glm::vec3 origin = offsetRayOrigin(sp.position, sp.normal);
  glm::dvec3 sum(0.0);
  for (const HtSample& s : samples) {
    glm::vec3 radiance = scene.environment.radiance[s.pixel];
    glm::vec3 fcos = s.averaged ? evalBsdf(*sp.material, ht.woLocal, ht.frame.toLocal(s.brdfDir))
                                : evalBsdf(*sp.material, woLocal, shading.toLocal(s.dir));
    if (fcos == glm::vec3(0.0f) || radiance == glm::vec3(0.0f)) continue;
    if (!unoccluded(scene, origin, s.dir, counters)) continue;
    sum += glm::dvec3(fcos * radiance) * double(s.weight);
  }
  counters.directions += hc.samples;
  counters.htNodes += hc.nodes;
  return glm::vec3(sum);
}

}  // namespace ht
