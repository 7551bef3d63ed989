#include "oracle.h"

#include <algorithm>
#include <array>
#include <vector>

#include "error.h"
#include "healpix.h"
#include "ht.h"
#include "sampling.h"
#include "tables.h"
#include "tree.h"

namespace ht {
namespace {

// Levels below the environment's pixels the refinement goes on: the
// environment is constant there but a glossy lobe or a shadow's edge is not.
constexpr int kVirtualLevels = 3;
// Share of every choice kept for unresolved nodes.
constexpr double kUnresolvedShare = 0.002;
// A node whose points are all shadowed but that is not surely dark (a
// shadow's edge crosses it) keeps this fraction of its unshadowed product:
// lit directions in it then weigh at most 1 / kShadowedWeight times their
// share, instead of the heavy tail a small common share gives.
constexpr double kShadowedWeight = 0.25;

// The three densities every choice mixes.
struct Weights {
  double product = 0.0;     // env x f cos x V at the points
  double unresolved = 0.0;  // env where no point is lit yet the node is not surely dark
  double env = 0.0;         // env
  bool belowSurface = false;  // unresolved with every point below the surface
  Weights& operator+=(const Weights& o) {
    product += o.product;
    unresolved += o.unresolved;
    env += o.env;
    return *this;
  }
};

// Probability of a choice with weights w among alternatives summing to `sum`:
// the product, but for a small share kept for the nodes whose points all
// missed the light (a shadow's edge, the horizon, a lobe between points), so
// that every lit direction keeps a non-zero density.
double share(const Weights& w, const Weights& sum) {
  double p = 0.0, left = 1.0;
  if (sum.unresolved > 0.0) {
    p += kUnresolvedShare * w.unresolved / sum.unresolved;
    left -= kUnresolvedShare;
  }
  return p + left * (sum.product > 0.0 ? w.product / sum.product : w.env / sum.env);
}

struct Point {
  const Scene& scene;
  const ShadingPoint& sp;
  const HtGeometry& geometry;
  const std::vector<Cap> dark;  // occluders' caps and the half-space below the surface
  const Frame frame;
  const glm::vec3 woLocal;
  const glm::vec3 origin;
  EstimateCounters& counters;
  mutable double peak = 0.0;  // the largest f cos seen

  // Luminance of f cos towards a node's centre, zero if it is shadowed (then
  // `shadowed` gets it).
  double product(int level, uint64_t node, double& shadowed) const {
    glm::vec3 c = scene.environment.direction(level, node, 0.5f, 0.5f);
    double v = luminance(evalBsdf(*sp.material, woLocal, frame.toLocal(c)));
    if (v <= 0.0) return 0.0;
    peak = std::max(peak, v);
    if (unoccluded(scene, origin, c, counters)) return v;
    shadowed += v;
    return 0.0;
  }

  bool surelyDark(int level, uint64_t node) const {
    glm::vec3 c = level <= geometry.order ? geometry.centers[MaxAvgTree::levelOffset(level) + node]
                                          : glm::vec3(healpix::pixToVec(level, node));
    for (const Cap& cap : dark)
      if (glm::dot(c, cap.axis) >= cap.cosInside[level]) return true;
    return false;
  }

  // A node with environment average e, judged by f cos V at its own centre
  // or at the centres of its four children. A node whose points are all
  // dark but that is not surely dark is unresolved, weighted by e times f cos
  // at its shadowed points (and kShadowedWeight of that as its product) or,
  // where every point lies below the surface, by e times the largest f cos
  // seen (set by the caller once it is known).
  Weights weights(int level, uint64_t node, double e, bool children) const {
    Weights w;
    w.env = e;
    if (e <= 0.0) return w;
    double shadowed = 0.0;
    if (children)
      for (uint64_t q = 0; q < 4; ++q) w.product += 0.25 * e * product(level + 1, 4 * node + q, shadowed);
    else
      w.product = e * product(level, node, shadowed);
    if (w.product == 0.0 && !surelyDark(level, node)) {
      w.product = kShadowedWeight * e * shadowed;
      w.unresolved = e * shadowed;
      w.belowSurface = shadowed == 0.0;
    }
    return w;
  }
};

std::vector<Cap> darkCaps(const Scene& scene, const ShadingPoint& sp, const HtGeometry& geometry) {
  // The oracle's product tree may go below the environment's order.
  constexpr int kLevels = 32;
  std::vector<Cap> caps = visibilityCaps(scene, sp, geometry, kLevels);
  glm::vec3 below = glm::normalize(glm::vec3(scene.environment.toHealpixFrame(-sp.normal)));
  caps.push_back(makeCap(below, 0.5f * kPi - 1e-3f, geometry, kLevels));
  return caps;
}

}  // namespace

glm::vec3 estimateOracle(const Scene& scene, const ShadingPoint& sp, int spp, int order, const HtGeometry& geometry,
                         PixelSampler& sampler, EstimateCounters& counters) {
  const Environment& env = scene.environment;
  if (!env.hasLight()) return glm::vec3(0.0f);
  const int k = std::clamp(order, 0, env.order);
  const int finest = env.order + kVirtualLevels;
  const uint64_t nodes = healpix::pixelCount(k);
  const Frame frame(sp.normal);
  if (geometry.order != env.order) throw Error("internal: oracle geometry of another order than the map's");
  const Point point{scene,   sp, geometry, darkCaps(scene, sp, geometry), frame, frame.toLocal(sp.wo),
                    offsetRayOrigin(sp.position, sp.normal), counters};

  thread_local std::vector<Weights> table;
  thread_local std::vector<double> cdf;
  table.resize(nodes);
  cdf.resize(nodes + 1);
  Weights sum;
  for (uint64_t p = 0; p < nodes; ++p) table[p] = point.weights(k, p, env.tree.avg(k, p), true);
  const double peak = point.peak;
  for (Weights& w : table) {
    if (w.belowSurface) w.unresolved = w.env * peak;
    sum += w;
  }
  cdf[0] = 0.0;
  for (uint64_t p = 0; p < nodes; ++p) cdf[p + 1] = cdf[p] + share(table[p], sum);
  const double total = cdf[nodes];

  glm::dvec3 result(0.0);
  for (int i = 0; i < spp; ++i) {
    // One point: u.x picks the table node and each child below it, rescaled
    // inside every pick, then places the direction in the finest cell with u.y.
    sampler.startSample(uint32_t(i));
    const glm::dvec2 u = sampler.get2DPrecise();
    double target = u.x * total;
    uint64_t node = uint64_t(std::upper_bound(cdf.begin() + 1, cdf.end(), target) - (cdf.begin() + 1));
    node = std::min(node, nodes - 1);
    while (cdf[node + 1] - cdf[node] <= 0.0) --node;  // never land on an empty node
    double prob = (cdf[node + 1] - cdf[node]) / total;
    double x = std::clamp((target - cdf[node]) / (cdf[node + 1] - cdf[node]), 0.0, kBelowOneD);
    for (int level = k + 1; level <= finest; ++level) {
      std::array<Weights, 4> w;
      Weights children;
      for (int j = 0; j < 4; ++j) {
        uint64_t child = 4 * node + uint64_t(j);
        w[j] = point.weights(level, child, level <= env.order ? double(env.tree.avg(level, child)) : 1.0, false);
        if (w[j].belowSurface) w[j].unresolved = w[j].env * peak;
        children += w[j];
      }
      std::array<double, 4> p;
      for (int j = 0; j < 4; ++j) p[j] = share(w[j], children);
      double before = 0.0;
      int pick = 0;
      while (pick < 3 && (p[pick] <= 0.0 || before + p[pick] <= x)) before += p[pick++];
      while (p[pick] <= 0.0) before -= p[--pick];
      x = std::clamp((x - before) / p[pick], 0.0, kBelowOneD);
      prob *= p[pick];
      node = 4 * node + uint64_t(pick);
    }
    glm::vec3 wi = env.direction(finest, node, std::min(float(x), kBelowOneF), std::min(float(u.y), kBelowOneF));
    ++counters.directions;
    glm::vec3 fcos = evalBsdf(*sp.material, point.woLocal, frame.toLocal(wi));
    if (fcos == glm::vec3(0.0f)) continue;
    if (!unoccluded(scene, point.origin, wi, counters)) continue;
    double pdf = prob / healpix::pixelSolidAngle(finest);
    result += glm::dvec3(fcos * env.radiance[node >> (2 * (finest - env.order))]) / pdf;
  }
  return glm::vec3(result / double(std::max(spp, 1)));
}

}  // namespace ht
