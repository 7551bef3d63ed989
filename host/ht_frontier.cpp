#include "ht_frontier.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <unordered_map>

#include <glm/geometric.hpp>

#include "healpix.h"
#include "tree.h"

namespace ht {
namespace {

// Refines a table from the 12 faces. `factor(level, i, bound, estimate,
// centre)` gives the bound B and estimate c of BRDF x cos (x visibility) over
// node i of the tree layout and the BRDF x cos at its centre, and returns
// false where the integrand is surely 0.
template <class Factor>
void refine(const Environment& env, const std::vector<glm::vec3>& centres, int refinements, float coarseRatio,
            Factor&& factor, FrontierTable& table) {
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
  auto push = [&](int level, uint64_t node) {
    const uint64_t i = MaxAvgTree::levelOffset(level) + node;
    const float avg = env.tree.avgv[i];
    float bound, c, centre;
    if (!(avg > 0.0f) || !factor(level, i, bound, c, centre)) return;
    const double energy = double(avg) * healpix::pixelSolidAngle(level);
    const FrontierNode nd{level, node, node << (2 * (order - level)), centres[i], energy * double(c), bound, centre};
    candidates.push_back({nd, false});
    // The variance a node adds grows with the spread of the factor over it.
    const double spread = std::max(0.0, double(bound) - double(c));
    const double priority = level < order ? energy * spread * spread / double(c) : 0.0;
    if (priority > 0.0) {
      heap.emplace_back(priority, uint32_t(candidates.size() - 1));
      std::push_heap(heap.begin(), heap.end());
    }
  };
  for (int f = 0; f < 12; ++f) push(0, uint64_t(f));
  for (; table.splits < refinements && !heap.empty(); ++table.splits) {
    std::pop_heap(heap.begin(), heap.end());
    const uint32_t top = heap.back().second;
    heap.pop_back();
    candidates[top].split = true;
    const int level = candidates[top].node.level + 1;
    const uint64_t first = 4 * candidates[top].node.node;
    for (uint64_t j = 0; j < 4; ++j) push(level, first + j);
  }
  for (const Candidate& c : candidates)
    if (!c.split) table.nodes.push_back(c.node);
  std::sort(table.nodes.begin(), table.nodes.end(),
            [](const FrontierNode& a, const FrontierNode& b) { return a.firstLeaf < b.firstLeaf; });
  double total = 0.0, coarse = 0.0;
  table.cum.resize(table.nodes.size() + 1);
  table.faceStart.fill(uint32_t(table.nodes.size()));
  for (size_t k = table.nodes.size(); k-- > 0;)
    table.faceStart[size_t(table.nodes[k].node >> (2 * table.nodes[k].level))] = uint32_t(k);
  for (int f = 11; f >= 0; --f) table.faceStart[size_t(f)] = std::min(table.faceStart[size_t(f)], table.faceStart[size_t(f + 1)]);
  for (size_t k = 0; k < table.nodes.size(); ++k) {
    const FrontierNode& nd = table.nodes[k];
    table.cum[k] = total;
    total += nd.mass;
    if (nd.brdfBound > coarseRatio * nd.brdfCentre) coarse += nd.mass;
  }
  table.cum.back() = total;
  table.coarseShare = total > 0.0 ? coarse / total : 0.0;
}

// A spherical cap of blocked directions seen from a shading point (HEALPix
// frame), by the cosine and sine of its half-angle: the caps of HT's
// visibility factor, shrunk by the same milliradian, without per-level tables.
struct LightCap {
  glm::vec3 axis;
  float cosA, sinA;
};

// HT's caps (visibilityCaps) with their half-angle A by its cosine and sine.
void lightCaps(const Scene& scene, const ShadingPoint& sp, std::vector<LightCap>& caps) {
  const float cm = std::cos(kCapMargin), sm = std::sin(kCapMargin);
  caps.clear();
  for (const Occluder& o : occluders(scene, sp)) {
    const float s0 = o.sinHalfAngle, c0 = std::sqrt(1.0f - s0 * s0);
    const float sinA = s0 * cm - c0 * sm;  // sin(asin(s0) - margin)
    if (sinA > 0.0f) caps.push_back({o.axis, c0 * cm + s0 * sm, sinA});
  }
}

// 0: a node of `level` at `centre` lies inside a cap (blocked), 1: outside
// every cap, 2: partly covered. Inside: angle(centre, axis) <= A - R with
// A > R; outside: >= A + R (A the cap's half-angle, R a radius bounding the
// level's nodes), in cosines by the angle-addition formulas; the caps'
// margin covers their rounding.
int visibilityClass(const std::vector<LightCap>& caps, const HtGeometry& g, const glm::vec3& centre, int level) {
  const float cR = g.levelCosRadius[size_t(level)], sR = g.levelSinRadius[size_t(level)];
  bool partial = false;
  for (const LightCap& c : caps) {
    const float d = glm::dot(centre, c.axis);
    if (c.sinA * cR - c.cosA * sR > 0.0f && d >= c.cosA * cR + c.sinA * sR) return 0;
    partial |= d > c.cosA * cR - c.sinA * sR;
  }
  return partial ? 2 : 1;
}

struct SharedKey {
  uint64_t tree;
  glm::vec3 normal;
  int refinements;
  float floor, coarseRatio;
  bool operator==(const SharedKey& o) const {
    return tree == o.tree && normal == o.normal && refinements == o.refinements && floor == o.floor &&
           coarseRatio == o.coarseRatio;
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
const FrontierTable& sharedLambertTable(const HtPoint& point, const FrontierOptions& options) {
  thread_local std::unordered_map<SharedKey, std::unique_ptr<FrontierTable>, SharedKeyHash> cache;
  thread_local uint64_t cachedTree = 0;
  const SharedKey key{point.env.tree.id, point.n, options.sharedRefinements, options.brdfFloor, options.coarseRatio};
  // Tables of an earlier environment are never used again.
  if (cachedTree != key.tree || cache.size() >= kFrontierSharedTables) cache.clear();
  cachedTree = key.tree;
  std::unique_ptr<FrontierTable>& entry = cache[key];
  if (entry) return *entry;
  entry = std::make_unique<FrontierTable>();
  const HtGeometry& g = point.geometry;
  // Albedo and 1/pi scale every node alike: the shape is cos+ alone.
  auto factor = [&](int, uint64_t i, float& bound, float& c, float& centre) {
    const glm::vec3& axis = g.centers[i];
    bound = cosClosest(axis, point.n, g.cosSinRadius[i].x, g.cosSinRadius[i].y);
    if (!(bound > 0.0f)) return false;
    centre = std::max(glm::dot(axis, point.n), 0.0f);
    c = std::max(centre, options.brdfFloor * bound);
    return true;
  };
  refine(point.env, g.centers, options.sharedRefinements, options.coarseRatio, factor, *entry);
  return *entry;
}

}  // namespace

int frontierRefinements(const FrontierOptions& options, int n) {
  return options.refinements >= 0 ? options.refinements : std::min(16 + std::max(n, 0), 256);
}

void Frontier::build(const HtPoint& point, const ShadingPoint& sp, const FrontierOptions& options, int n) {
  point_ = &point;
  order_ = point.env.order;
  thread_local std::vector<LightCap> allCaps;
  allCaps.clear();
  if (options.visibility) lightCaps(point.scene, sp, allCaps);
  const bool lambert = point.material.type == MaterialType::Lambert && !point.table;
  if (sp.flat && lambert && options.sharedRefinements >= 0 && point.woLocal.z > 0.0f) {
    table_ = &sharedLambertTable(point, options);
    // The point's own caps, each with the faces it can reach. The cap of
    // the surface's own plane is left out: the table has no mass below it
    // but for nodes the horizon cuts, where cos+ is small.
    thread_local std::array<std::vector<LightCap>, 12> faceCaps;
    const HtGeometry& g = point.geometry;
    touched_ = 0;
    for (std::vector<LightCap>& caps : faceCaps) caps.clear();
    for (const LightCap& c : allCaps) {
      if (glm::dot(c.axis, point.n) < -0.9999f) continue;
      const float cosOutside = c.cosA * g.levelCosRadius[0] - c.sinA * g.levelSinRadius[0];
      for (uint32_t f = 0; f < 12; ++f)
        if (glm::dot(g.centers[f], c.axis) > cosOutside) {
          faceCaps[f].push_back(c);
          touched_ |= 1u << f;
        }
    }
    const FrontierTable& t = *table_;
    mass_.resize(t.nodes.size());
    cum_.resize(t.nodes.size());
    for (uint32_t f = 0; f < 12; ++f) {
      if (!(touched_ & (1u << f))) continue;
      double acc = 0.0;
      for (uint32_t k = t.faceStart[f]; k < t.faceStart[f + 1]; ++k) {
        const FrontierNode& nd = t.nodes[k];
        const int cls = visibilityClass(faceCaps[f], g, nd.centre, nd.level);
        mass_[k] = cls == 0 ? 0.0 : cls == 2 ? nd.mass * double(options.partialVisibility) : nd.mass;
        cum_[k] = acc;
        acc += mass_[k];
      }
    }
  } else {
    table_ = &own_;
    auto factor = [&](int level, uint64_t i, float& bound, float& c, float& centre) {
      bound = point.brdfBound(i);
      if (!(bound > 0.0f)) return false;
      float vis = 1.0f;
      if (options.visibility) {
        const int cls = visibilityClass(allCaps, point.geometry, point.geometry.centers[i], level);
        if (cls == 0) return false;
        if (cls == 2) vis = options.partialVisibility;
      }
      centre = point.brdfValue(point.geometry.centers[i]);
      c = std::max(centre, options.brdfFloor * bound) * vis;
      return true;
    };
    refine(point.env, point.geometry.centers, frontierRefinements(options, n), options.coarseRatio, factor, own_);
    touched_ = 0;
  }
  const FrontierTable& t = *table_;
  total_ = 0.0;
  for (uint32_t f = 0; f < 12; ++f) {
    faceCum_[f] = total_;
    const uint32_t first = t.faceStart[f], end = t.faceStart[f + 1];
    if (touched_ & (1u << f))
      total_ += end > first ? cum_[end - 1] + mass_[end - 1] : 0.0;
    else
      total_ += t.cum[end] - t.cum[first];
  }
  faceCum_[12] = total_;
}

double Frontier::mass(size_t k) const {
  return touched_ & (1u << faceOf(table_->nodes[k])) ? mass_[k] : table_->nodes[k].mass;
}

double Frontier::cumInFace(size_t k, int face) const {
  return touched_ & (1u << face) ? cum_[k] : table_->cum[k] - table_->cum[table_->faceStart[size_t(face)]];
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

// The node's share times the probability of the leaf on the way down the
// average tree, per unit solid angle.
double Frontier::density(size_t k, uint64_t leaf) const {
  const MaxAvgTree& tree = point_->env.tree;
  const int top = table_->nodes[k].level;
  double p = mass(k) / total_;
  for (int level = order_; level > top; --level) {
    const uint64_t first = MaxAvgTree::levelOffset(level) + (leaf & ~uint64_t(3));
    const double sum = double(tree.avgv[first]) + double(tree.avgv[first + 1]) + double(tree.avgv[first + 2]) +
                       double(tree.avgv[first + 3]);
    p *= double(tree.avgv[first + (leaf & 3)]) / sum;
    leaf >>= 2;
  }
  return p / healpix::pixelSolidAngle(order_);
}

double Frontier::pdf(uint64_t leaf) const {
  const size_t k = nodeOfLeaf(leaf);
  return k < table_->nodes.size() && mass(k) > 0.0 ? density(k, leaf) : 0.0;
}

uint64_t Frontier::sample(double x, const glm::vec2& jitter, glm::dvec3& dirHp, double& pdf) const {
  const MaxAvgTree& tree = point_->env.tree;
  const FrontierTable& tb = *table_;
  // The face, then the node, whose interval of the mass CDF holds x.
  const double target = x * total_;
  int face = 11;
  while (face > 0 && !(faceCum_[size_t(face)] <= target && faceCum_[size_t(face) + 1] > faceCum_[size_t(face)])) --face;
  while (!(faceCum_[size_t(face) + 1] > faceCum_[size_t(face)])) ++face;
  const double r = target - faceCum_[size_t(face)];
  const uint32_t first = tb.faceStart[size_t(face)], end = tb.faceStart[size_t(face) + 1];
  size_t lo = first, hi = end;  // the last k with cumInFace(k) <= r
  while (hi - lo > 1) {
    const size_t mid = (lo + hi) / 2;
    (cumInFace(mid, face) <= r ? lo : hi) = mid;
  }
  size_t k = lo;
  while (k > first && !(mass(k) > 0.0)) --k;
  while (!(mass(k) > 0.0)) ++k;
  const FrontierNode& nd = tb.nodes[k];
  const double share = mass(k) / total_;
  double t = std::clamp((r - cumInFace(k, face)) / mass(k), 0.0, 1.0);
  double p = share;
  uint64_t node = nd.node;
  for (int level = nd.level + 1; level <= order_; ++level) {
    const uint64_t first = MaxAvgTree::levelOffset(level) + 4 * node;
    const double a[4] = {tree.avgv[first], tree.avgv[first + 1], tree.avgv[first + 2], tree.avgv[first + 3]};
    const double sum = a[0] + a[1] + a[2] + a[3];
    double target = t * sum, acc = 0.0;
    int j = 0;
    while (j < 3 && (a[j] <= 0.0 || acc + a[j] <= target)) {
      acc += a[j];
      ++j;
    }
    while (a[j] <= 0.0) --j;  // the last child with radiance
    t = std::clamp((target - acc) / a[j], 0.0, 1.0);
    p *= a[j] / sum;
    node = 4 * node + uint64_t(j);
  }
  pdf = p / healpix::pixelSolidAngle(order_);
  dirHp = healpix::pixToVec(order_, node, jitter.x, jitter.y);
  return node;
}

int frontierBrdfCount(const Frontier& frontier, const FrontierOptions& options, int n) {
  const double share = std::min(frontier.coarseShare(), double(options.maxBrdfShare));
  // At least one direction from the table: a lone BRDF sample would miss the
  // light the table finds.
  return std::clamp(int(std::lround(share * n)), 0, std::max(n - 1, 0));
}

glm::vec3 estimateHtFrontier(const Scene& scene, const ShadingPoint& sp, const FrontierOptions& options, int n,
                             Rng& rng, PixelSampler& sampler, EstimateCounters& counters, const MethodTables& tables) {
  const Environment& env = scene.environment;
  if (!env.hasLight() || n <= 0) return glm::vec3(0.0f);
  // The caps are the frontier's own; the point brings bounds and geometry.
  HtOptions htOptions;
  htOptions.budgetRefinements = -1;
  const HtPoint point(scene, sp, htOptions, tables);
  thread_local Frontier frontier;
  frontier.build(point, sp, options, n);
  if (!frontier.shared()) counters.htNodes += uint64_t(12 + 4 * frontier.splits());
  if (!(frontier.totalMass() > 0.0)) return glm::vec3(0.0f);
  const Shading sh(scene, sp, counters);
  const int nb = frontierBrdfCount(frontier, options, n);
  const int nt = n - nb;
  glm::dvec3 sum(0.0);
  // Systematic points over the table's CDF, one offset per pixel; inside
  // its leaf each point takes the sampler's point of sample i, dimension 0.
  // The BRDF directions are samples 0..nb-1 of dimension 1.
  const double u = rng.next();
  for (int i = 0; i < nt; ++i) {
    glm::dvec3 hp;
    double pt;
    sampler.startSample(uint32_t(i));
    const uint64_t leaf = frontier.sample((double(i) + u) / nt, sampler.get2D(), hp, pt);
    const glm::vec3 wi = env.fromHealpixFrame(hp);
    const double pb = nb > 0 ? double(bsdfPdf(sh.material, sh.woLocal, sh.frame.toLocal(wi))) : 0.0;
    const glm::vec3 f = sh.reflected(wi, env.radiance[leaf]);
    if (f != glm::vec3(0.0f)) sum += glm::dvec3(f) / (nt * pt + nb * pb);
  }
  for (int i = 0; i < nb; ++i) {
    sampler.startSample(uint32_t(i));
    sampler.setDimension(1);
    const glm::vec3 local = sampleBsdf(sh.material, sh.woLocal, sampler.get2D());
    const double pb = bsdfPdf(sh.material, sh.woLocal, local);
    if (!(pb > 0.0)) continue;
    const glm::vec3 wi = sh.frame.toWorld(local);
    const uint64_t leaf = env.pixelOf(wi);
    const glm::vec3 f = sh.reflected(wi, env.radiance[leaf]);
    if (f != glm::vec3(0.0f)) sum += glm::dvec3(f) / (nt * frontier.pdf(leaf) + nb * pb);
  }
  counters.directions += uint64_t(n);
  return glm::vec3(sum);
}

}  // namespace ht
