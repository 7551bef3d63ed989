#include "ht_frontier.h"

#include <algorithm>
#include <cmath>

#include "healpix.h"
#include "tree.h"

namespace ht {

int frontierRefinements(const FrontierOptions& options, int n) {
  return options.refinements >= 0 ? options.refinements : std::min(16 + std::max(n, 0), 256);
}

void Frontier::build(const HtPoint& point, const FrontierOptions& options, int n) {
  const int refinements = frontierRefinements(options, n);
  point_ = &point;
  order_ = point.env.order;
  candidates_.clear();
  heap_.clear();
  nodes_.clear();
  total_ = coarse_ = 0.0;
  splits_ = 0;
  const MaxAvgTree& tree = point.env.tree;
  double mass = 0.0;  // of the current frontier
  auto push = [&](int level, uint64_t node) {
    const uint64_t i = MaxAvgTree::levelOffset(level) + node;
    const float avg = tree.avgv[i];
    if (!(avg > 0.0f)) return;
    const float bound = point.brdfBound(i);
    if (!(bound > 0.0f)) return;
    float vis = 1.0f;
    if (options.visibility) {
      const int cls = point.visibilityClass(point.geometry.centers[i], level);
      if (cls == 0) return;
      if (cls == 2) vis = options.partialVisibility;
    }
    const float c = std::max(point.brdfValue(point.geometry.centers[i]), options.brdfFloor * bound) * vis;
    const double energy = double(avg) * healpix::pixelSolidAngle(level);
    const FrontierNode nd{level, node, node << (2 * (order_ - level)), energy * double(c), 0.0, avg, bound, c};
    const double priority = level < order_ ? energy * std::max(0.0, double(bound) - double(c)) : 0.0;
    candidates_.push_back({nd, priority, false});
    mass += nd.mass;
    if (priority > 0.0) {
      heap_.emplace_back(priority, uint32_t(candidates_.size() - 1));
      std::push_heap(heap_.begin(), heap_.end());
    }
  };
  for (int f = 0; f < 12; ++f) push(0, uint64_t(f));
  for (; splits_ < refinements && !heap_.empty(); ++splits_) {
    if (heap_.front().first < options.tolerance * mass) break;
    std::pop_heap(heap_.begin(), heap_.end());
    const uint32_t top = heap_.back().second;
    heap_.pop_back();
    candidates_[top].split = true;
    mass -= candidates_[top].node.mass;
    const int level = candidates_[top].node.level + 1;
    const uint64_t first = 4 * candidates_[top].node.node;
    for (uint64_t j = 0; j < 4; ++j) push(level, first + j);
  }
  for (const Candidate& c : candidates_)
    if (!c.split) nodes_.push_back(c.node);
  std::sort(nodes_.begin(), nodes_.end(),
            [](const FrontierNode& a, const FrontierNode& b) { return a.firstLeaf < b.firstLeaf; });
  double coarse = 0.0;
  for (FrontierNode& nd : nodes_) {
    nd.cdf = total_;
    total_ += nd.mass;
    if (nd.brdfBound > options.coarseRatio * nd.estimate) coarse += nd.mass;
  }
  if (total_ > 0.0) {
    for (FrontierNode& nd : nodes_) nd.cdf /= total_;
    coarse_ = coarse / total_;
  }
}

size_t Frontier::nodeOfLeaf(uint64_t leaf) const {
  auto it = std::upper_bound(nodes_.begin(), nodes_.end(), leaf,
                             [](uint64_t l, const FrontierNode& nd) { return l < nd.firstLeaf; });
  if (it == nodes_.begin()) return nodes_.size();
  --it;
  const uint64_t leaves = uint64_t(1) << (2 * (order_ - it->level));
  return leaf - it->firstLeaf < leaves ? size_t(it - nodes_.begin()) : nodes_.size();
}

// The node's share times the probability of the leaf on the way down the
// average tree, per unit solid angle.
double Frontier::density(const FrontierNode& nd, uint64_t leaf) const {
  const MaxAvgTree& tree = point_->env.tree;
  double p = nd.mass / total_;
  for (int level = order_; level > nd.level; --level) {
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
  return k < nodes_.size() ? density(nodes_[k], leaf) : 0.0;
}

uint64_t Frontier::sample(double x, const glm::vec2& jitter, glm::dvec3& dirHp, double& pdf) const {
  const MaxAvgTree& tree = point_->env.tree;
  auto it = std::upper_bound(nodes_.begin(), nodes_.end(), x,
                             [](double v, const FrontierNode& nd) { return v < nd.cdf; });
  const FrontierNode& nd = *(it == nodes_.begin() ? it : it - 1);
  const double share = nd.mass / total_;
  double t = std::clamp((x - nd.cdf) / share, 0.0, 1.0);
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
  return std::clamp(int(std::lround(share * n)), 0, n);
}

glm::vec3 estimateHtFrontier(const Scene& scene, const ShadingPoint& sp, const FrontierOptions& options, int n,
                             Rng& rng, EstimateCounters& counters) {
  const Environment& env = scene.environment;
  if (!env.hasLight() || n <= 0) return glm::vec3(0.0f);
  HtOptions htOptions;
  htOptions.visibility = options.visibility;
  htOptions.budgetRefinements = -1;
  const HtPoint point(scene, sp, htOptions);
  thread_local Frontier frontier;
  frontier.build(point, options, n);
  counters.htNodes += uint64_t(12 + 4 * frontier.splits());
  if (!(frontier.totalMass() > 0.0)) return glm::vec3(0.0f);
  const Shading sh(scene, sp, counters);
  const int nb = frontierBrdfCount(frontier, options, n);
  const int nt = n - nb;
  glm::dvec3 sum(0.0);
  const double u = rng.next();
  for (int i = 0; i < nt; ++i) {
    glm::dvec3 hp;
    double pt;
    const uint64_t leaf = frontier.sample((double(i) + u) / nt, rng.next2(), hp, pt);
    const glm::vec3 wi = env.fromHealpixFrame(hp);
    const double pb = nb > 0 ? double(bsdfPdf(sh.material, sh.woLocal, sh.frame.toLocal(wi))) : 0.0;
    const glm::vec3 f = sh.reflected(wi, env.radiance[leaf]);
    if (f != glm::vec3(0.0f)) sum += glm::dvec3(f) / (nt * pt + nb * pb);
  }
  for (int i = 0; i < nb; ++i) {
    const glm::vec3 local = sampleBsdf(sh.material, sh.woLocal, rng.next3());
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
