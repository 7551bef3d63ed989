#include "ht_frontier.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <memory>
#include <unordered_map>
#include <utility>

#include <glm/geometric.hpp>
#include <glm/vec4.hpp>

#include "error.h"
#include "healpix.h"
#include "tables.h"
#include "tree.h"

namespace ht {
namespace {

// A node's chroma (FrontierColours::chroma, or its leaf's).
glm::vec3 nodeChroma(const Environment& env, const FrontierColours& colours, int level, uint64_t node) {
  return level < env.order ? colours.chroma[MaxAvgTree::levelOffset(level) + node]
                           : glm::vec3(frontierLeafChroma(env.radiance[node]));
}

// The mean chroma of the directions a node of class `cls` draws: its
// descent's where it is free, its own where caps cover it in part (the
// control variate then takes the node's chroma, not its leaf's).
glm::dvec3 colourMeanOf(const FrontierNode& nd, int cls) {
  return glm::dvec3(cls == 1 ? nd.descentChroma : nd.chroma);
}

// FrontierTable::faceColour from the nodes' masses and classes.
void sumFaceColours(FrontierTable& table) {
  table.faceColour.fill(glm::dvec4(0.0));
  for (const FrontierNode& nd : table.nodes)
    table.faceColour[size_t(nd.node >> (2 * nd.level))] +=
        nd.mass * glm::dvec4(glm::dvec3(nd.kappa) * colourMeanOf(nd, nd.visibility), 1.0);
}

// Frontier::children's BRDF factors on the product levels: each child's
// BRDF x cos at its centre (`value`; 0 for a child without light or inside
// a cap), never below the floor times the largest of its siblings'.
void productFactors(const double w[4], const int cls[4], const double value[4], float floor, double b[4]) {
  double top = 0.0;
  for (int j = 0; j < 4; ++j) {
    b[j] = w[j] > 0.0 && cls[j] != 0 ? value[j] : 0.0;
    top = std::max(top, b[j]);
  }
  for (int j = 0; j < 4; ++j) b[j] = top > 0.0 ? std::max(b[j], double(floor) * top) : 1.0;
}

// The mean chroma of the leaf that the descent of a shared (cos+) table
// reaches from a free node: by the product down to `productLevel`, by the
// average tree below, where the node's own chroma is the mean (a leaf's is
// its own).
glm::dvec3 freeDescentChroma(const Environment& env, const HtGeometry& g, const FrontierColours& colours,
                             const glm::vec3& n, float floor, int productLevel, int level, uint64_t node) {
  if (level >= productLevel || level >= env.order) return glm::dvec3(nodeChroma(env, colours, level, node));
  const uint64_t first = MaxAvgTree::levelOffset(level + 1) + 4 * node;
  double w[4], value[4], b[4];
  const int cls[4] = {1, 1, 1, 1};
  for (int j = 0; j < 4; ++j) {
    w[j] = env.tree.avgv[first + uint64_t(j)];
    value[j] = double(std::max(glm::dot(frontierFactorDirection(colours, g, first + uint64_t(j)), n), 0.0f));
  }
  productFactors(w, cls, value, floor, b);
  double p[4];
  for (int j = 0; j < 4; ++j) p[j] = w[j] * b[j];
  if (p[0] + p[1] + p[2] + p[3] > 0.0)
    for (int j = 0; j < 4; ++j) w[j] = p[j];
  const double sum = w[0] + w[1] + w[2] + w[3];
  glm::dvec3 mean(0.0);
  if (!(sum > 0.0)) return mean;
  for (int j = 0; j < 4; ++j)
    if (w[j] > 0.0)
      mean += w[j] / sum *
              freeDescentChroma(env, g, colours, n, floor, productLevel, level + 1, 4 * node + uint64_t(j));
  return mean;
}

// Refines a table from the 12 faces. `factor(level, i, bound, estimate,
// centre)` gives the bound B and estimate c of BRDF x cos (x visibility) over
// node i of the tree layout and the BRDF x cos at its centre, and returns
// false where the integrand is surely 0. Nodes on `productLevel` and below
// are exact for colour; their chroma is read only `withChroma`.
template <class Factor>
void refine(const Environment& env, const std::vector<glm::vec3>& centres, const FrontierColours& colours,
            bool colourOrder, bool withChroma, int productLevel, int refinements, float coarseRatio, Factor&& factor,
            FrontierTable& table) {
  struct Candidate {
    FrontierNode node;
    bool split;
  };
  thread_local std::vector<Candidate> candidates;
  thread_local std::vector<std::pair<double, uint32_t>> heap;
  candidates.clear();
  heap.clear();
  table.nodes.clear();
  table.splits = 0;
  table.coarseShare = 0.0;
  const int order = env.order;
  // `visibility`: the parent's class; the children of a free node are free.
  auto push = [&](int level, uint64_t node, int visibility) {
    const uint64_t i = MaxAvgTree::levelOffset(level) + node;
    const float avg = env.tree.avgv[i];
    float bound, c, centre;
    glm::vec3 kappa(1.0f);
    if (!(avg > 0.0f) || !factor(level, i, bound, c, centre, visibility, kappa)) return;
    const double energy = double(avg) * healpix::pixelSolidAngle(level);
    const glm::vec3 chroma = withChroma ? nodeChroma(env, colours, level, node) : glm::vec3(0.0f);
    const FrontierNode nd{level,  node,   node << (2 * (order - level)), centres[i], energy * double(c), bound, centre,
                          visibility, chroma, chroma, level >= productLevel, kappa};
    candidates.push_back({nd, false});
    // The variance a node adds grows with the spread of the factor over it.
    const double spread = std::max(0.0, double(bound) - double(c));
    const double priority = level < order ? energy * spread * spread / double(c) : 0.0;
    if (priority > 0.0) {
      heap.emplace_back(priority, uint32_t(candidates.size() - 1));
      std::push_heap(heap.begin(), heap.end());
    }
  };
  for (int f = 0; f < 12; ++f) push(0, uint64_t(f), 2);
  for (; table.splits < refinements && !heap.empty(); ++table.splits) {
    std::pop_heap(heap.begin(), heap.end());
    const uint32_t top = heap.back().second;
    heap.pop_back();
    candidates[top].split = true;
    const int level = candidates[top].node.level + 1;
    const uint64_t first = 4 * candidates[top].node.node;
    for (uint64_t j = 0; j < 4; ++j) push(level, first + j, candidates[top].node.visibility);
  }
  for (const Candidate& c : candidates)
    if (!c.split) table.nodes.push_back(c.node);
  std::sort(table.nodes.begin(), table.nodes.end(),
            [](const FrontierNode& a, const FrontierNode& b) { return a.firstLeaf < b.firstLeaf; });
  // The CDF's order: by colour bin and face, along the nested index inside
  // each (a counting sort: the nodes are in nested order).
  auto segment = [&](const FrontierNode& nd) {
    const int bin = colourOrder ? colours.bins[MaxAvgTree::levelOffset(nd.level) + nd.node] : 0;
    return bin * 12 + int(nd.node >> (2 * nd.level));
  };
  table.faceStart.fill(0);
  for (const FrontierNode& nd : table.nodes) ++table.faceStart[size_t(nd.node >> (2 * nd.level)) + 1];
  for (size_t f = 0; f < 12; ++f) table.faceStart[f + 1] += table.faceStart[f];
  table.segStart.fill(0);
  for (const FrontierNode& nd : table.nodes) ++table.segStart[size_t(segment(nd)) + 1];
  for (int i = 0; i < FrontierTable::kSegments; ++i) table.segStart[size_t(i) + 1] += table.segStart[size_t(i)];
  std::array<uint32_t, FrontierTable::kSegments> next;
  std::copy(table.segStart.begin(), table.segStart.end() - 1, next.begin());
  table.cdfOrder.resize(table.nodes.size());
  for (uint32_t k = 0; k < uint32_t(table.nodes.size()); ++k)
    table.cdfOrder[next[size_t(segment(table.nodes[k]))]++] = k;
  double total = 0.0, coarse = 0.0;
  table.cum.resize(table.nodes.size() + 1);
  for (size_t i = 0; i < table.cdfOrder.size(); ++i) {
    const FrontierNode& nd = table.nodes[table.cdfOrder[i]];
    table.cum[i] = total;
    total += nd.mass;
    if (nd.brdfBound > coarseRatio * nd.brdfCentre) coarse += nd.mass;
  }
  table.cum.back() = total;
  table.coarseShare = total > 0.0 ? coarse / total : 0.0;
}

// HT's caps (visibilityCaps), each with its per-level thresholds. With A
// the cap's half-angle and R a radius bounding a level's nodes, a node lies
// inside when angle(centre, axis) <= A - R (A > R), outside when >= A + R,
// in cosines by the angle-addition formulas; the caps' margin covers their
// rounding.
void lightCaps(const Scene& scene, const ShadingPoint& sp, const HtGeometry& g, std::vector<LightCap>& caps) {
  caps.clear();
  for (const Occluder& o : occluders(scene, sp)) {
    LightCap c;
    if (frontierCap(o.axis, o.sinHalfAngle, g, c)) caps.push_back(c);
  }
}

}  // namespace

bool frontierCap(const glm::vec3& axis, float sinHalfAngle, const HtGeometry& g, LightCap& c) {
  const float cm = std::cos(kCapMargin), sm = std::sin(kCapMargin);
  const float s0 = sinHalfAngle, c0 = std::sqrt(1.0f - s0 * s0);
  const float sinA = s0 * cm - c0 * sm;  // sin(asin(s0) - margin)
  const float cosA = c0 * cm + s0 * sm;
  if (!(sinA > 0.0f)) return false;
  c.axis = axis;
  c.cosInside.fill(2.0f);    // never inside
  c.cosOutside.fill(-2.0f);  // never outside
  for (size_t l = 0; l <= size_t(g.order); ++l) {
    const float cR = g.levelCosRadius[l], sR = g.levelSinRadius[l];
    c.cosInside[l] = sinA * cR - cosA * sR > 0.0f ? cosA * cR + sinA * sR : 2.0f;
    c.cosOutside[l] = cosA * cR - sinA * sR;
  }
  return true;
}

namespace {

// Caps: a range of const LightCap& (the point's caps, or those of one face).
template <class Caps>
int visibilityUnder(const Caps& caps, const glm::vec3& centre, int level, float minPartial, float& factor) {
  bool partial = false;
  float visible = 1.0f;
  for (const LightCap& c : caps) {
    const float d = glm::dot(centre, c.axis);
    const float inside = c.cosInside[size_t(level)], outside = c.cosOutside[size_t(level)];
    if (d >= inside) {
      factor = 0.0f;
      return 0;
    }
    if (d > outside) {
      partial = true;
      visible = std::min(visible, 1.0f - std::min((d - outside) / (std::min(inside, 1.0f) - outside), 1.0f));
    }
  }
  factor = partial ? std::max(visible, minPartial) : 1.0f;
  return partial ? 2 : 1;
}

// `centre`: the node's, g.centers[levelOffset(level) + node].
template <class Caps>
int nodeVisibilityUnder(const Caps& caps, const HtGeometry& g, int level, uint64_t node, const glm::vec3& centre,
                        float minPartial, float& factor) {
  const int cls = visibilityUnder(caps, centre, level, minPartial, factor);
  if (cls != 2 || level > kFrontierShareLevel || level >= g.order) return cls;
  // frontierVisibility of each child, under the caps that cover the node in
  // part (a node outside a cap is taken to have its children outside it).
  const uint64_t first = MaxAvgTree::levelOffset(level + 1) + 4 * node;
  const size_t l = size_t(level) + 1;
  float visible[4] = {1.0f, 1.0f, 1.0f, 1.0f};
  bool partial[4] = {false, false, false, false};
  for (const LightCap& c : caps) {
    if (!(glm::dot(centre, c.axis) > c.cosOutside[size_t(level)])) continue;
    const float inside = c.cosInside[l], outside = c.cosOutside[l];
    for (int j = 0; j < 4; ++j) {
      const float d = glm::dot(g.centers[first + uint64_t(j)], c.axis);
      if (d >= inside) {
        visible[j] = 0.0f;
      } else if (d > outside) {
        partial[j] = true;
        visible[j] = std::min(visible[j], 1.0f - std::min((d - outside) / (std::min(inside, 1.0f) - outside), 1.0f));
      }
    }
  }
  float share = 0.0f;
  for (int j = 0; j < 4; ++j) share += partial[j] && visible[j] > 0.0f ? std::max(visible[j], minPartial) : visible[j];
  factor = std::max(0.25f * share, minPartial);
  return cls;
}

}  // namespace

int frontierVisibility(const std::vector<LightCap>& caps, const glm::vec3& centre, int level, float minPartial,
                       float& factor) {
  return visibilityUnder(caps, centre, level, minPartial, factor);
}

int frontierNodeVisibility(const std::vector<LightCap>& caps, const HtGeometry& g, int level, uint64_t node,
                           float minPartial, float& factor) {
  return nodeVisibilityUnder(caps, g, level, node, g.centers[MaxAvgTree::levelOffset(level) + node], minPartial,
                             factor);
}

namespace {

struct SharedKey {
  uint64_t tree;
  glm::vec3 normal;
  int refinements, productLevel;
  float floor, coarseRatio;
  bool colourOrder;
  bool operator==(const SharedKey& o) const {
    return tree == o.tree && normal == o.normal && refinements == o.refinements && productLevel == o.productLevel &&
           floor == o.floor && coarseRatio == o.coarseRatio && colourOrder == o.colourOrder;
  }
};
struct SharedKeyHash {
  size_t operator()(const SharedKey& k) const {
    uint32_t b[3];
    std::memcpy(b, &k.normal, sizeof b);
    uint64_t h = k.tree * 0x9e3779b97f4a7c15ull;
    for (uint32_t v : b) h = (h ^ v) * 0xbf58476d1ce4e5b9ull;
    return size_t(h ^ (h >> 31) ^ uint64_t(uint32_t(k.refinements)));
  }
};

// The Lambert table of a flat surface's normal, per thread.
const FrontierTable& sharedLambertTable(const HtPoint& point, const FrontierOptions& options,
                                       const FrontierColours& colours) {
  thread_local std::unordered_map<SharedKey, std::unique_ptr<FrontierTable>, SharedKeyHash> cache;
  thread_local uint64_t cachedTree = 0;
  const SharedKey key{point.env.tree.id, point.n,           options.sharedRefinements, options.productLevel,
                      options.brdfFloor,  options.coarseRatio, options.colourOrder};
  // Tables of an earlier environment are never used again.
  if (cachedTree != key.tree || cache.size() >= kFrontierSharedTables) cache.clear();
  cachedTree = key.tree;
  std::unique_ptr<FrontierTable>& entry = cache[key];
  if (entry) return *entry;
  entry = std::make_unique<FrontierTable>();
  buildSharedFrontierTable(point.env, point.geometry, point.n, options, colours, *entry);
  return *entry;
}

}  // namespace

glm::vec3 frontierSurfaceNormal(const Environment& env, const glm::vec3& normal) {
  return glm::normalize(glm::vec3(env.toHealpixFrame(normal)));
}

void buildSharedFrontierTable(const Environment& env, const HtGeometry& g, const glm::vec3& n,
                              const FrontierOptions& options, const FrontierColours& colours, FrontierTable& table) {
  // Albedo and 1/pi scale every node alike: the shape is cos+ alone. Where
  // the floor lifts a node's factor above its centre value, its directions'
  // f / p is centre / c of the rest's (the control variate's kappa).
  auto factor = [&](int, uint64_t i, float& bound, float& c, float& centre, int& visibility, glm::vec3& kappa) {
    visibility = 1;
    bound = cosClosest(g.centers[i], n, g.cosSinRadius[i].x, g.cosSinRadius[i].y);
    if (!(bound > 0.0f)) return false;
    centre = std::max(glm::dot(frontierFactorDirection(colours, g, i), n), 0.0f);
    c = std::max(centre, options.brdfFloor * bound);
    kappa = glm::vec3(centre / c);
    return true;
  };
  refine(env, g.centers, colours, options.colourOrder, true, options.productLevel, options.sharedRefinements,
         options.coarseRatio, factor, table);
  // Every point of the plane descends from a free node alike.
  for (FrontierNode& nd : table.nodes) {
    nd.descentChroma = glm::vec3(
        freeDescentChroma(env, g, colours, n, options.brdfFloor, options.productLevel, nd.level, nd.node));
    nd.exactColour = true;
  }
  sumFaceColours(table);
}

namespace {

// Whether nodes of radius r resolve the material's specular lobe: its
// half-width (GGX alpha, Phong sqrt(2 / exponent) / 2) is at least
// kFrontierLobeRadii x r. A Lambert has no lobe to resolve.
bool lobeResolved(const Material& m, float r) {
  const float kr = kFrontierLobeRadii * r;
  if (m.type == MaterialType::Ggx) return m.alpha >= kr;
  if (m.type == MaterialType::Phong) return 2.0f / m.exponent >= 4.0f * kr * kr;
  return true;
}

}  // namespace

int frontierProductLevel(const Material& m, const HtGeometry& g, const FrontierOptions& options) {
  int level = std::clamp(options.productLevel, 0, g.order);
  while (level < g.order && !lobeResolved(m, g.levelRadius[size_t(level)])) ++level;
  return level;
}

float frontierLobeFloor(const Material& m, const HtGeometry& g, const FrontierOptions& options, int productLevel) {
  return m.type != MaterialType::Lambert && lobeResolved(m, g.levelRadius[size_t(productLevel)]) ? options.lobeFloor
                                                                                                 : options.brdfFloor;
}

int frontierRefinements(const FrontierOptions& options, int n) {
  return options.refinements >= 0 ? options.refinements : std::min(16 + std::max(n, 0), 256);
}

glm::dvec3 frontierLeafChroma(const glm::vec3& radiance) {
  const float l = luminance(radiance);
  return l > 0.0f ? glm::dvec3(radiance) / double(l) : glm::dvec3(0.0);
}

namespace {

// FrontierColours::chroma: radiance and luminance summed in double, level
// by level from the leaves.
std::vector<glm::vec3> chromaAboveLeaves(const Environment& env) {
  const int order = env.order;
  std::vector<glm::dvec4> sum(size_t(MaxAvgTree::levelOffset(order)));
  auto leaf = [&](uint64_t i) {
    const glm::vec3& r = env.radiance[i];
    return glm::dvec4(glm::dvec3(r), double(luminance(r)));
  };
  for (int level = order - 1; level >= 0; --level)
    for (uint64_t i = 0; i < (uint64_t(12) << (2 * level)); ++i) {
      glm::dvec4 s(0.0);
      for (uint64_t j = 0; j < 4; ++j)
        s += level + 1 == order ? leaf(4 * i + j) : sum[MaxAvgTree::levelOffset(level + 1) + 4 * i + j];
      sum[MaxAvgTree::levelOffset(level) + i] = s;
    }
  std::vector<glm::vec3> chroma(sum.size());
  for (size_t i = 0; i < sum.size(); ++i)
    chroma[i] = sum[i].w > 0.0 ? glm::vec3(glm::dvec3(sum[i]) / sum[i].w) : glm::vec3(0.0f);
  return chroma;
}

std::vector<uint8_t> colourBins(const Environment& env) {
  const int order = env.order;
  std::vector<glm::vec3> sum(size_t(MaxAvgTree::levelOffset(order + 1)));
  std::copy(env.radiance.begin(), env.radiance.end(), sum.begin() + std::ptrdiff_t(MaxAvgTree::levelOffset(order)));
  for (int level = order - 1; level >= 0; --level)
    for (uint64_t i = 0; i < (uint64_t(12) << (2 * level)); ++i) {
      const uint64_t c = MaxAvgTree::levelOffset(level + 1) + 4 * i;
      sum[MaxAvgTree::levelOffset(level) + i] = sum[c] + sum[c + 1] + sum[c + 2] + sum[c + 3];
    }
  std::vector<uint8_t> bins(sum.size());
  for (size_t i = 0; i < sum.size(); ++i) {
    const float all = sum[i].r + sum[i].g + sum[i].b;
    const float key = all > 0.0f ? (sum[i].b - sum[i].r) / all : 0.0f;
    bins[i] = uint8_t(std::clamp(int((key + 1.0f) * 0.5f * kFrontierColourBins), 0, kFrontierColourBins - 1));
  }
  return bins;
}

// FrontierColours::centroid: luminance x centre summed in double, level by
// level from the leaves.
std::vector<glm::vec3> centroidsAboveLeaves(const Environment& env, const HtGeometry& g) {
  const int order = env.order;
  std::vector<glm::dvec3> sum(size_t(MaxAvgTree::levelOffset(order)));
  const uint64_t leaves = MaxAvgTree::levelOffset(order);
  auto leaf = [&](uint64_t i) { return double(env.tree.avgv[leaves + i]) * glm::dvec3(g.centers[leaves + i]); };
  for (int level = order - 1; level >= 0; --level)
    for (uint64_t i = 0; i < MaxAvgTree::levelSize(level); ++i) {
      glm::dvec3 s(0.0);
      for (uint64_t j = 0; j < 4; ++j)
        s += level + 1 == order ? leaf(4 * i + j) : sum[MaxAvgTree::levelOffset(level + 1) + 4 * i + j];
      sum[MaxAvgTree::levelOffset(level) + i] = s;
    }
  std::vector<glm::vec3> centroid(sum.size());
  for (size_t i = 0; i < sum.size(); ++i) {
    const double l = glm::length(sum[i]);
    centroid[i] = l > 0.0 ? glm::vec3(sum[i] / l) : g.centers[i];
  }
  return centroid;
}

}  // namespace

FrontierColours frontierColours(const Environment& env, const HtGeometry& g) {
  if (g.order != env.order) throw Error("internal: ht-frontier colours need the geometry of the map's order");
  FrontierColours c;
  c.chroma = chromaAboveLeaves(env);
  c.bins = colourBins(env);
  c.centroid = centroidsAboveLeaves(env, g);
  return c;
}

void Frontier::build(const HtPoint& point, const ShadingPoint& sp, const FrontierOptions& options, int n,
                     const FrontierColours& colours) {
  point_ = &point;
  colours_ = &colours;
  order_ = point.env.order;
  brdfFloor_ = options.brdfFloor;
  minPartialVisibility_ = options.minPartialVisibility;
  const bool lambert = point.material.type == MaterialType::Lambert;
  const bool shared = sp.flat && !point.table && options.sharedRefinements >= 0 && point.woLocal.z > 0.0f;
  // A shared table is the diffuse lobe's: its descent keeps the option's level.
  productLevel_ = shared ? options.productLevel : frontierProductLevel(point.material, point.geometry, options);
  specularApart_ = shared && !lambert;
  cosFactor_ = (lambert && !point.table) || specularApart_;
  caps_.clear();
  if (options.visibility) lightCaps(point.scene, sp, point.geometry, caps_);
  touched_ = 0;
  std::array<glm::dvec4, 12> faceColour;
  if (shared) {
    colour_ = options.colourControl;
    table_ = &sharedLambertTable(point, options, colours);
    // The point's own caps, each with the faces it can reach. The cap of
    // the surface's own plane is left out: the table has no mass below it
    // but for nodes the horizon cuts, where cos+ is small.
    thread_local std::array<std::vector<std::reference_wrapper<const LightCap>>, 12> faceCaps;
    const HtGeometry& g = point.geometry;
    for (auto& caps : faceCaps) caps.clear();
    caps_.erase(std::remove_if(caps_.begin(), caps_.end(),
                               [&](const LightCap& c) { return glm::dot(c.axis, point.n) < -0.9999f; }),
                caps_.end());
    for (const LightCap& c : caps_) {
      for (uint32_t f = 0; f < 12; ++f)
        if (glm::dot(g.centers[f], c.axis) > c.cosOutside[0]) {
          faceCaps[f].push_back(c);
          touched_ |= 1u << f;
        }
    }
    const FrontierTable& t = *table_;
    if (touched_) {
      mass_.resize(t.nodes.size());
      class_.resize(t.nodes.size());
      cum_.resize(t.nodes.size());
    }
    faceColour = t.faceColour;
    for (uint32_t f = 0; f < 12; ++f) {
      if (!(touched_ >> f & 1u)) continue;
      glm::dvec4 colour(0.0);
      for (uint32_t k = t.faceStart[f]; k < t.faceStart[f + 1]; ++k) {
        const FrontierNode& nd = t.nodes[k];
        float factor;
        const int cls =
            nodeVisibilityUnder(faceCaps[f], g, nd.level, nd.node, nd.centre, options.minPartialVisibility, factor);
        mass_[k] = cls == 1 ? nd.mass : nd.mass * double(factor);
        class_[k] = uint8_t(cls);
        colour += mass_[k] * glm::dvec4(glm::dvec3(nd.kappa) * colourMeanOf(nd, cls), 1.0);
      }
      faceColour[f] = colour;
      for (int bin = 0; bin < kFrontierColourBins; ++bin) {
        const size_t seg = size_t(bin * 12) + f;
        double acc = 0.0;
        for (uint32_t i = t.segStart[seg]; i < t.segStart[seg + 1]; ++i) {
          cum_[i] = acc;
          acc += mass_[t.cdfOrder[i]];
        }
      }
    }
  } else {
    table_ = &own_;
    const float lobeFloor = frontierLobeFloor(point.material, point.geometry, options, productLevel_);
    auto factor = [&](int level, uint64_t i, float& bound, float& c, float& centre, int& visibility, glm::vec3& kappa) {
      float diffuse;
      bound = point.brdfBound(i, diffuse);
      if (!(bound > 0.0f)) return false;
      float vis = 1.0f;
      if (!options.visibility) {
        visibility = 1;
      } else if (visibility == 2) {
        visibility = frontierNodeVisibility(caps_, point.geometry, level, i - MaxAvgTree::levelOffset(level),
                                            options.minPartialVisibility, vis);
        if (visibility == 0) return false;
      }
      // The control variate's kappa: a direction's f / p per unit of its
      // light's chroma, the BRDF's colour read where its factor is.
      const glm::vec3 f = point.brdfColour(frontierFactorDirection(colours, point.geometry, i));
      centre = luminance(f);
      const float floor = options.brdfFloor * diffuse + lobeFloor * (bound - diffuse);
      const float top = std::max(centre, floor);
      kappa = top > 0.0f ? f / top : glm::vec3(0.0f);
      c = top * vis;
      return true;
    };
    colour_ = options.colourControl;
    refine(point.env, point.geometry.centers, colours, options.colourOrder, colour_, productLevel_,
           frontierRefinements(options, n), options.coarseRatio, factor, own_);
    if (colour_) sumFaceColours(own_);
    else own_.faceColour.fill(glm::dvec4(0.0));
    faceColour = own_.faceColour;
  }
  glm::dvec4 colour(0.0);
  for (const glm::dvec4& c : faceColour) colour += c;
  colourAverage_ = colour.w > 0.0 ? glm::dvec3(colour) / colour.w : glm::dvec3(0.0);
  const FrontierTable& t = *table_;
  total_ = 0.0;
  for (size_t seg = 0; seg < size_t(FrontierTable::kSegments); ++seg) {
    segCum_[seg] = total_;
    const uint32_t first = t.segStart[seg], end = t.segStart[seg + 1];
    if (first == end) continue;
    if (touched_ >> (seg % 12) & 1u)
      total_ += cum_[end - 1] + mass_[t.cdfOrder[end - 1]];
    else
      total_ += t.cum[end] - t.cum[first];
  }
  segCum_.back() = total_;
}

double Frontier::mass(size_t k) const {
  const FrontierNode& nd = table_->nodes[k];
  return touched(nd) ? mass_[k] : nd.mass;
}

int Frontier::visibility(size_t k) const {
  const FrontierNode& nd = table_->nodes[k];
  return touched(nd) ? class_[k] : nd.visibility;
}

size_t Frontier::nodeOfLeaf(uint64_t leaf) const {
  const std::vector<FrontierNode>& nodes = table_->nodes;
  auto it = std::upper_bound(nodes.begin(), nodes.end(), leaf,
                             [](uint64_t l, const FrontierNode& nd) { return l < nd.firstLeaf; });
  if (it == nodes.begin()) return nodes.size();
  --it;
  const uint64_t leaves = uint64_t(1) << (2 * (order_ - it->level));
  return leaf - it->firstLeaf < leaves ? size_t(it - nodes.begin()) : nodes.size();
}

void Frontier::children(int level, uint64_t parent, int parentClass, double w[4], int cls[4]) const {
  const MaxAvgTree& tree = point_->env.tree;
  const uint64_t first = MaxAvgTree::levelOffset(level) + 4 * parent;
  double v[4];
  for (int j = 0; j < 4; ++j) {
    w[j] = tree.avgv[first + uint64_t(j)];
    cls[j] = parentClass;
    v[j] = 1.0;
  }
  const bool product = level <= productLevel_;
  if (!product && parentClass != 2) return;
  const HtGeometry& g = point_->geometry;
  if (parentClass == 2)
    for (int j = 0; j < 4; ++j) {
      float factor;
      cls[j] = frontierNodeVisibility(caps_, g, level, 4 * parent + uint64_t(j), minPartialVisibility_, factor);
      v[j] = double(factor);
    }
  double b[4] = {1.0, 1.0, 1.0, 1.0};
  if (product) {
    double value[4];
    for (int j = 0; j < 4; ++j) {
      const glm::vec3& d = frontierFactorDirection(*colours_, g, first + uint64_t(j));
      value[j] = w[j] > 0.0 && cls[j] != 0 ? cosFactor_ ? double(std::max(glm::dot(d, point_->n), 0.0f))
                                                         : double(point_->brdfValue(d))
                                           : 0.0;
    }
    // A child the integrand may reach keeps a weight above 0: its BRDF
    // factor is at least the floor times its siblings' largest.
    productFactors(w, cls, value, brdfFloor_, b);
  }
  double p[4];
  for (int j = 0; j < 4; ++j) p[j] = w[j] * b[j] * v[j];
  // Caps over all four children leave the environment's weights.
  if (p[0] + p[1] + p[2] + p[3] > 0.0)
    for (int j = 0; j < 4; ++j) w[j] = p[j];
}

// The node's share times the probability of each choice on the way down to
// the leaf, per unit solid angle.
double Frontier::density(size_t k, uint64_t leaf) const {
  double p = mass(k) / total_;
  int cls = visibility(k);
  for (int level = table_->nodes[k].level + 1; level <= order_; ++level) {
    const uint64_t node = leaf >> (2 * (order_ - level));
    double w[4];
    int c[4];
    children(level, node >> 2, cls, w, c);
    p *= w[node & 3] / (w[0] + w[1] + w[2] + w[3]);
    cls = c[node & 3];
  }
  return p / healpix::pixelSolidAngle(order_);
}

glm::dvec3 Frontier::colourOf(size_t k, uint64_t leaf) const {
  const FrontierNode& nd = table_->nodes[k];
  return glm::dvec3(nd.kappa) *
         (visibility(k) == 1 && nd.exactColour ? frontierLeafChroma(point_->env.radiance[leaf]) : glm::dvec3(nd.chroma));
}

glm::dvec3 Frontier::colourMean(size_t k) const {
  return glm::dvec3(table_->nodes[k].kappa) * colourMeanOf(table_->nodes[k], visibility(k));
}

double Frontier::pdf(uint64_t leaf) const {
  const size_t k = nodeOfLeaf(leaf);
  return k < table_->nodes.size() && mass(k) > 0.0 ? density(k, leaf) : 0.0;
}

uint64_t Frontier::sample(double x, const glm::vec2& jitter, glm::dvec3& dirHp, double& pdf, size_t* nodeOut) const {
  const FrontierTable& tb = *table_;
  // The segment, then the node, whose interval of the CDF holds x (one with
  // mass: empty intervals are never strictly above their start).
  const double target = x * total_;
  size_t seg = size_t(std::upper_bound(segCum_.begin() + 1, segCum_.end(), target) - segCum_.begin()) - 1;
  seg = std::min(seg, size_t(FrontierTable::kSegments - 1));
  while (seg > 0 && !(segCum_[seg + 1] > segCum_[seg])) --seg;
  const bool own = touched_ >> (seg % 12) & 1u;
  const uint32_t first = tb.segStart[seg], end = tb.segStart[seg + 1];
  // Mass of the segment's nodes before position i.
  auto before = [&](size_t i) { return own ? cum_[i] : tb.cum[i] - tb.cum[first]; };
  const double r = target - segCum_[seg];
  size_t lo = first, hi = end;  // the last position with before(i) <= r
  while (hi - lo > 1) {
    const size_t mid = (lo + hi) / 2;
    (before(mid) <= r ? lo : hi) = mid;
  }
  size_t i = lo;
  while (i > first && !(mass(tb.cdfOrder[i]) > 0.0)) --i;
  while (!(mass(tb.cdfOrder[i]) > 0.0)) ++i;
  const size_t k = tb.cdfOrder[i];
  if (nodeOut) *nodeOut = k;
  double t = std::clamp((r - before(i)) / mass(k), 0.0, 1.0);
  double p = mass(k) / total_;
  uint64_t node = tb.nodes[k].node;
  int cls = visibility(k);
  for (int level = tb.nodes[k].level + 1; level <= order_; ++level) {
    double a[4];
    int c[4];
    children(level, node, cls, a, c);
    const double sum = a[0] + a[1] + a[2] + a[3];
    const double target = t * sum;
    double acc = 0.0;
    int j = 0;
    while (j < 3 && (a[j] <= 0.0 || acc + a[j] <= target)) {
      acc += a[j];
      ++j;
    }
    while (a[j] <= 0.0) --j;  // the last child with weight
    t = std::clamp((target - acc) / a[j], 0.0, 1.0);
    p *= a[j] / sum;
    node = 4 * node + uint64_t(j);
    cls = c[j];
  }
  pdf = p / healpix::pixelSolidAngle(order_);
  dirHp = healpix::pixToVec(order_, node, jitter.x, jitter.y);
  return node;
}

}  // namespace ht
