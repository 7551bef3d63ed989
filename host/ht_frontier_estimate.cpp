// ht-frontier's estimate at one shading point: the table's directions and
// the BRDF's, combined by the balance heuristic, with the control variate on
// colour (the table itself: ht_frontier.cpp).
#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "healpix.h"
#include "ht_frontier.h"
#include "tables.h"
#include "tree.h"

namespace ht {

int frontierBrdfCount(const Frontier& frontier, const FrontierOptions& options, int n) {
  return frontierBrdfCount(frontier.coarseShare(), options, n);
}

Material specularLobeOf(const Material& m) {
  Material lobe = m;
  lobe.diffuse = glm::vec3(0.0f);
  return lobe;
}

namespace {

// frontierLobeCount's S and D.
std::pair<double, double> lobeAndDiffuse(const Material& m, float cosO, float mirrorRadiance, double tableMass) {
  const float f0 = luminance(m.specular);
  const float t = 1.0f - std::clamp(cosO, 0.0f, 1.0f);
  const float reflectance = m.type == MaterialType::Ggx ? f0 + (1.0f - f0) * (t * t * t * t * t) : f0;
  return {double(reflectance) * double(mirrorRadiance), double(luminance(m.diffuse)) * double(kInvPi) * tableMass};
}

}  // namespace

int frontierLobeCount(const Material& m, float cosO, float mirrorRadiance, double tableMass, int n) {
  const auto [lobe, diffuse] = lobeAndDiffuse(m, cosO, mirrorRadiance, tableMass);
  if (!(lobe > 0.0) || n < 2) return 0;
  return std::clamp(int(std::lround(double(n) * lobe / (lobe + diffuse))), 1, n - 1);
}

double frontierLobeMixture(const Material& m, float cosO, float mirrorRadiance, double tableMass) {
  const auto [lobe, diffuse] = lobeAndDiffuse(m, cosO, mirrorRadiance, tableMass);
  if (!(lobe > 0.0)) return 0.0;
  return std::clamp(lobe / (lobe + diffuse), kFrontierMixtureMin, 1.0 - kFrontierMixtureMin);
}

int frontierBrdfCount(double coarseShare, const FrontierOptions& options, int n) {
  const double share = std::min(coarseShare, double(options.maxBrdfShare));
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
  frontier.build(point, sp, options, n, tables.own<FrontierColours>());
  if (!frontier.shared()) counters.htNodes += uint64_t(12 + 4 * frontier.splits());
  if (!(frontier.totalMass() > 0.0)) return glm::vec3(0.0f);
  const Shading sh(scene, sp, counters);
  // The BRDF technique: the specular lobe alone where the table is the
  // diffuse lobe's, else the whole BRDF.
  const bool apart = frontier.specularApart();
  const Material bm = apart ? specularLobeOf(sh.material) : sh.material;
  const int lobeLevel = std::min(kFrontierLobeLevel, env.order);
  const float mirrorRadiance =
      apart ? env.tree.avgv[MaxAvgTree::levelOffset(lobeLevel) + healpix::vecToPix(lobeLevel, glm::dvec3(point.mirror))]
            : 0.0f;
  int nb = apart ? frontierLobeCount(sh.material, point.woLocal.z, mirrorRadiance, frontier.totalMass(), n)
                 : frontierBrdfCount(frontier, options, n);
  int nt = n - nb;
  // The techniques' weights in the balance heuristic: their counts, or for
  // one direction with the lobe apart the mixture's probabilities, the
  // offset u then choosing the technique (frontierLobeMixture).
  double wt = nt, wb = nb;
  double u = rng.next();
  const double q =
      apart && n == 1 ? frontierLobeMixture(sh.material, point.woLocal.z, mirrorRadiance, frontier.totalMass()) : 0.0;
  if (q > 0.0) {
    wt = 1.0 - q;
    wb = q;
    if (u < q) {
      nt = 0;
      nb = 1;
    } else {
      u = (u - q) / (1.0 - q);
    }
  }
  // The control variate's M / n: a table direction's f / p is about
  // M x kappa x its chroma (Frontier::colourOf), and a shared table's
  // kappa leaves out the albedo / pi, which its mass does not hold.
  glm::dvec3 colourScale(0.0);
  if (frontier.colourControl()) {
    colourScale = frontier.shared() ? glm::dvec3(sh.material.diffuse) * double(kInvPi) : glm::dvec3(1.0);
    // With the mixture a table direction comes with probability wt.
    colourScale = colourScale * frontier.totalMass() / (double(n) * (q > 0.0 ? wt : 1.0));
  }
  const bool colourControl = colourScale != glm::dvec3(0.0);
  const glm::dvec3& colourAverage = frontier.colourAverage();
  glm::dvec3 sum(0.0);
  // Systematic points over the table's CDF, one offset per pixel; inside
  // its leaf each point takes the sampler's point of sample i, dimension 0.
  // The BRDF directions are samples 0..nb-1 of dimension 1.
  for (int i = 0; i < nt; ++i) {
    glm::dvec3 hp;
    double pt;
    sampler.startSample(uint32_t(i));
    size_t k;
    const uint64_t leaf = frontier.sample((double(i) + u) / nt, sampler.get2D(), hp, pt, &k);
    if (colourControl) sum += colourScale * (colourAverage - frontier.colourOf(k, leaf));
    const glm::vec3 wi = env.fromHealpixFrame(hp);
    const double pb = wb > 0.0 ? double(bsdfPdf(bm, sh.woLocal, sh.frame.toLocal(wi))) : 0.0;
    const glm::vec3 f = sh.reflected(wi, env.radiance[leaf]);
    if (f != glm::vec3(0.0f)) sum += glm::dvec3(f) / (wt * pt + wb * pb);
  }
  for (int i = 0; i < nb; ++i) {
    sampler.startSample(uint32_t(i));
    sampler.setDimension(1);
    const glm::vec3 local = sampleBsdf(bm, sh.woLocal, sampler.get2D());
    const double pb = bsdfPdf(bm, sh.woLocal, local);
    if (!(pb > 0.0)) continue;
    const glm::vec3 wi = sh.frame.toWorld(local);
    const uint64_t leaf = env.pixelOf(wi);
    const glm::vec3 f = sh.reflected(wi, env.radiance[leaf]);
    if (f != glm::vec3(0.0f)) sum += glm::dvec3(f) / (wt * frontier.pdf(leaf) + wb * pb);
  }
  counters.directions += uint64_t(n);
  // The control variate can take a dark channel below 0, rarely (docs/ht.md).
  return glm::vec3(glm::max(sum, glm::dvec3(0.0)));
}

}  // namespace ht
