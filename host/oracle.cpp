#include "oracle.h"

#include <algorithm>
#include <vector>

#include "healpix.h"
#include "sampling.h"
#include "tree.h"

namespace ht {

glm::vec3 estimateOracle(const Scene& scene, const ShadingPoint& sp, int spp, int order, Rng& rng,
                         EstimateCounters& counters) {
  const Environment& env = scene.environment;
  if (!env.hasLight()) return glm::vec3(0.0f);
  const int k = std::clamp(order, 0, env.order);
  const uint64_t nodes = healpix::pixelCount(k);
  const Frame frame(sp.normal);
  const glm::vec3 woLocal = frame.toLocal(sp.wo);
  const glm::vec3 origin = offsetRayOrigin(sp.position, sp.normal);

  thread_local std::vector<double> cdf;
  thread_local std::vector<float> product;
  cdf.resize(nodes + 1);
  product.resize(nodes);
  float largest = 0.0f;
  for (uint64_t p = 0; p < nodes; ++p) {
    float e = env.tree.avg(k, p);
    product[p] = 0.0f;
    if (e <= 0.0f) continue;
    // Mean of f cos V over 2 x 2 points of the node.
    float f = 0.0f;
    for (int q = 0; q < 4; ++q) {
      glm::vec3 c = env.direction(k, p, 0.25f + 0.5f * float(q & 1), 0.25f + 0.5f * float(q >> 1));
      float v = luminance(evalBsdf(*sp.material, woLocal, frame.toLocal(c)));
      if (v > 0.0f) {
        ++counters.shadowRays;
        if (!occluded(scene, origin, c)) f += 0.25f * v;
      }
    }
    largest = std::max(largest, f);
    product[p] = f;
  }
  // Four points miss what a node's edges see: a floor keeps every lit node
  // reachable, so the estimate stays unbiased.
  const float floor = 1e-2f * largest + 1e-30f;
  cdf[0] = 0.0;
  for (uint64_t p = 0; p < nodes; ++p)
    cdf[p + 1] = cdf[p] + double(env.tree.avg(k, p)) * double(product[p] + floor);
  const double total = cdf[nodes];

  glm::dvec3 sum(0.0);
  for (int i = 0; i < spp; ++i) {
    double target = double(rng.next()) * total;
    uint64_t node = uint64_t(std::upper_bound(cdf.begin() + 1, cdf.end(), target) - (cdf.begin() + 1));
    node = std::min(node, nodes - 1);
    while (cdf[node + 1] - cdf[node] <= 0.0) --node;  // never land on an empty node
    double prob = (cdf[node + 1] - cdf[node]) / total;
    // Descend to a pixel in proportion to the environment.
    for (int level = k + 1; level <= env.order; ++level) {
      const float* w = &env.tree.avgv[MaxAvgTree::levelOffset(level) + 4 * node];
      float s = w[0] + w[1] + w[2] + w[3];
      float u = rng.next() * s, acc = 0.0f;
      int pick = 3;
      for (int j = 0; j < 4; ++j) {
        acc += w[j];
        if (u < acc && w[j] > 0.0f) {
          pick = j;
          break;
        }
      }
      while (w[pick] <= 0.0f) --pick;
      prob *= double(w[pick] / s);
      node = 4 * node + uint64_t(pick);
    }
    glm::vec3 wi = env.direction(env.order, node, rng.next(), rng.next());
    ++counters.directions;
    glm::vec3 fcos = evalBsdf(*sp.material, woLocal, frame.toLocal(wi));
    if (fcos == glm::vec3(0.0f)) continue;
    ++counters.shadowRays;
    if (occluded(scene, origin, wi)) continue;
    double pdf = prob / env.pixelSolidAngle();
    sum += glm::dvec3(fcos * env.radiance[node]) / pdf;
  }
  return glm::vec3(sum / double(std::max(spp, 1)));
}

}  // namespace ht
