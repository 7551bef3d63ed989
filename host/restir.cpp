#include "restir.h"

#include <algorithm>
#include <cstdio>

#include <glm/geometric.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "bsdf.h"
#include "ris.h"
#include "rng.h"

namespace ht {

RestirOptions restirOptionsFor(Method method, const MethodOptions& o) {
  return {std::max(o.risCandidates, 1), std::clamp(o.restirNeighbours, 0, HT_RESTIR_MAX_NEIGHBOURS),
          std::max(o.restirRadius, 1), std::max(o.restirRounds, 0), method == Method::Restir};
}

RestirPoint restirPoint(const Scene& scene, int width, int height, int x, int y) {
  RestirPoint p{};
  p.material = HT_RESTIR_NO_HIT;
  const Ray ray = cameraRay(scene.camera, width, height, x + 0.5f, y + 0.5f);
  Hit hit;
  if (!intersectScene(scene, ray, 0.0f, INFINITY, hit)) return p;
  p.position = hit.position;
  p.material = uint32_t(hit.material);
  p.normal = hit.normal;
  p.wo = -ray.dir;
  p.planar = hit.flat ? 1u : 0u;
  // The camera's axis as the GPU's scene holds it (cameraRay's w).
  const glm::vec3 w = glm::normalize(scene.camera.lookAt - scene.camera.position);
  const glm::vec3 d = hit.position - scene.camera.position;
  const float dx = d.x * w.x, dy = d.y * w.y, dz = d.z * w.z;
  p.depth = (dx + dy) + dz;
  return p;
}

ShadingPoint shadingPointOf(const Scene& scene, const RestirPoint& p) {
  return {p.position, p.normal, p.wo, &scene.materials[p.material], p.planar != 0};
}

uint32_t restirRoundSeed(uint32_t seed, int round, int chain) {
  return hashCombine(hashCombine(seed, 0x52535452u + uint32_t(round)), uint32_t(chain));
}

namespace {

// p_hat at a point: luminance(L f cos), unshadowed (RisSampler::target).
float targetAt(const Scene& scene, const RestirPoint& p, const Reservoir& r) {
  const Frame frame(p.normal);
  const glm::vec3 product = r.radiance * evalBsdf(scene.materials[p.material], frame.toLocal(p.wo), frame.toLocal(r.dir));
  return luminance(product);
}

bool similar(const RestirPoint& a, const RestirPoint& b) {
  if (b.material == HT_RESTIR_NO_HIT) return false;
  const float nx = a.normal.x * b.normal.x, ny = a.normal.y * b.normal.y, nz = a.normal.z * b.normal.z;
  const float cosine = (nx + ny) + nz;
  const float gap = std::abs(b.depth - a.depth), allowed = kRestirDepthShare * a.depth;
  return cosine >= kRestirNormalCos && gap <= allowed;
}

}  // namespace

Reservoir restirInitial(const Scene& scene, const RestirPoint& p, const RestirOptions& o, int chain,
                        PixelSampler& sampler, EstimateCounters& counters) {
  const ShadingPoint sp = shadingPointOf(scene, p);
  const RisSampler ris(scene.environment, *sp.material, sp.normal, sp.wo);
  const RisSample s = ris.sample(o.candidates, sampler, uint32_t(chain));
  counters.directions += uint64_t(s.candidates);
  Reservoir r{s.chosen.dir, float(s.contributionWeight()), s.chosen.radiance, uint32_t(s.candidates)};
  if (!o.unbiased && r.W > 0.0f && !unoccluded(scene, offsetRayOrigin(p.position, p.normal), r.dir, counters))
    r.W = 0.0f;
  return r;
}

Reservoir restirRound(const Scene& scene, const std::vector<RestirPoint>& points, const Reservoir* previous,
                      int width, int height, int x, int y, const RestirOptions& o, uint32_t roundSeed) {
  const size_t self = size_t(y) * width + x;
  const RestirPoint& q = points[self];
  Rng rng(roundSeed, uint32_t(self));
  // The reservoirs taken: q's own first, then the neighbours that pass.
  constexpr int kMaxTaken = 1 + HT_RESTIR_MAX_NEIGHBOURS;
  size_t taken[kMaxTaken];
  int count = 0;
  taken[count++] = self;
  const uint32_t side = 2u * uint32_t(o.radius) + 1u;
  for (int j = 0; j < o.neighbours; ++j) {
    const int dx = int(rng.nextUint() % side) - o.radius;
    const int dy = int(rng.nextUint() % side) - o.radius;
    const int nx = x + dx, ny = y + dy;
    if ((dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= width || ny >= height) continue;
    const size_t n = size_t(ny) * width + nx;
    if (similar(q, points[n])) taken[count++] = n;
  }
  double weightSum = 0.0;
  uint32_t confidence = 0;
  int chosen = -1;
  for (int i = 0; i < count; ++i) {
    const Reservoir& r = previous[taken[i]];
    confidence += r.M;
    const float t = r.W > 0.0f ? targetAt(scene, q, r) : 0.0f;
    double w = 0.0;
    if (t > 0.0f) {
      if (o.unbiased) {
        // The balance heuristic over the reservoirs taken: M_i p_hat_i(y_i) / sum_j M_j p_hat_j(y_i).
        double own = 0.0, all = 0.0;
        for (int j = 0; j < count; ++j) {
          const double term = double(previous[taken[j]].M) * double(targetAt(scene, points[taken[j]], r));
          all += term;
          if (j == i) own = term;
        }
        w = own / all * double(t) * double(r.W);
      } else {
        w = double(t) * double(r.W) * double(r.M);
      }
    }
    const float u = rng.next();
    if (!(w > 0.0)) continue;
    weightSum += w;
    if (double(u) * weightSum < w) chosen = i;
  }
  Reservoir out{previous[self].dir, 0.0f, previous[self].radiance, confidence};
  if (chosen < 0) return out;
  out.dir = previous[taken[chosen]].dir;
  out.radiance = previous[taken[chosen]].radiance;
  const double target = double(targetAt(scene, q, out));
  out.W = float(o.unbiased ? weightSum / target : weightSum / (double(confidence) * target));
  return out;
}

glm::dvec3 restirShade(const Scene& scene, const RestirPoint& p, const Reservoir& r, const RestirOptions& o,
                       EstimateCounters& counters) {
  if (!(r.W > 0.0f)) return glm::dvec3(0.0);
  // The biased variant's W is zero where y is blocked at q before any round.
  if ((o.unbiased || o.rounds > 0) && !unoccluded(scene, offsetRayOrigin(p.position, p.normal), r.dir, counters))
    return glm::dvec3(0.0);
  const Frame frame(p.normal);
  const glm::vec3 fcos = evalBsdf(scene.materials[p.material], frame.toLocal(p.wo), frame.toLocal(r.dir));
  const glm::vec3 product = r.radiance * fcos;
  return glm::dvec3(product) * double(r.W);
}

void renderRestir(const Scene& scene, const RenderSettings& s, RenderResult& out) {
  const RestirOptions o = restirOptionsFor(s.method, s.options);
  const int width = s.width, height = s.height;
  const size_t pixels = size_t(width) * height;
  std::vector<RestirPoint> points(pixels);
  std::vector<uint32_t> samplerSeeds(pixels);
  std::vector<Reservoir> reservoirs[2] = {std::vector<Reservoir>(pixels), std::vector<Reservoir>(pixels)};
  std::vector<glm::dvec3> sums(pixels, glm::dvec3(0.0));
  std::vector<EstimateCounters> counters(pixels);
  auto forRows = [&](auto&& body) {
    tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
      for (int y = rows.begin(); y != rows.end(); ++y)
        for (int x = 0; x < width; ++x) body(x, y, size_t(y) * width + x);
    });
  };
  forRows([&](int x, int y, size_t i) {
    points[i] = restirPoint(scene, width, height, x, y);
    samplerSeeds[i] = Rng(s.seed, pixelStream(x, y, width)).nextUint();  // estimateDirect's first draw
    if (points[i].material == HT_RESTIR_NO_HIT)
      out.image.pixels[i] = scene.environment.eval(cameraRay(scene.camera, width, height, x + 0.5f, y + 0.5f).dir);
  });
  const int spp = std::max(s.spp, 1);
  for (int chain = 0; chain < spp; ++chain) {
    forRows([&](int, int, size_t i) {
      if (points[i].material == HT_RESTIR_NO_HIT) return;
      PixelSampler sampler(s.options.sampler, samplerSeeds[i]);
      reservoirs[0][i] = restirInitial(scene, points[i], o, chain, sampler, counters[i]);
    });
    for (int round = 1; round <= o.rounds; ++round) {
      const std::vector<Reservoir>& from = reservoirs[(round - 1) & 1];
      std::vector<Reservoir>& to = reservoirs[round & 1];
      const uint32_t seed = restirRoundSeed(s.seed, round, chain);
      forRows([&](int x, int y, size_t i) {
        if (points[i].material == HT_RESTIR_NO_HIT) return;
        to[i] = restirRound(scene, points, from.data(), width, height, x, y, o, seed);
      });
    }
    const std::vector<Reservoir>& last = reservoirs[o.rounds & 1];
    forRows([&](int, int, size_t i) {
      if (points[i].material == HT_RESTIR_NO_HIT) return;
      sums[i] += restirShade(scene, points[i], last[i], o, counters[i]);
    });
    if (s.progress) {
      const int before = int(100.0 * chain / spp), percent = int(100.0 * (chain + 1) / spp);
      if (percent / 10 > before / 10 || chain + 1 == spp) {
        std::fprintf(stderr, "\rrender: %3d%%%s", percent, chain + 1 == spp ? "\n" : "");
        std::fflush(stderr);
      }
    }
  }
  for (size_t i = 0; i < pixels; ++i) {
    if (points[i].material == HT_RESTIR_NO_HIT) continue;
    out.image.pixels[i] = glm::vec3(sums[i] / double(spp));
    out.counters.directions += counters[i].directions;
    out.counters.shadowRays += counters[i].shadowRays;
    ++out.shadedPixels;
    if (s.pixelCounts) out.pixelDirections[i] = uint32_t(counters[i].directions);
  }
}

}  // namespace ht
