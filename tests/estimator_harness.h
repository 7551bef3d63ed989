// Shared set-up for estimator tests: shading points with a known integral
// (brute force over every HEALPix pixel) and independent repeated estimates.
#pragma once

#include <cmath>
#include <map>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>
#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include "environment.h"
#include "healpix.h"
#include "image_io.h"
#include "integrator.h"
#include "sampling.h"
#include "scene.h"

namespace ht::test {

// The sun of the test environments, and the direction mirroring it about +y.
inline const glm::vec3 kSunDir = glm::normalize(glm::vec3(0.5f, 0.6f, 0.3f));
inline glm::vec3 mirrorOf(glm::vec3 d) { return {-d.x, d.y, -d.z}; }

#ifdef HT_TEST_DATA
// data/env/sunrise.exr resampled at 2^order.
inline Environment sunriseAt(int order) {
  ImageRGB img = readExr(std::string(HT_TEST_DATA) + "/env/sunrise.exr");
  sanitizeEnvironmentImage(img, "sunrise.exr");
  return environmentFromEquirect(img, order, 0.0f, 1.0f);
}
#endif

// A dim sky with a single bright pixel at kSunDir; `blackHalf` blacks out
// the first half of the nested pixels (the northern faces and part of the
// equator).
inline Environment onePixelSun(int order, float background = 0.02f, bool blackHalf = false) {
  std::vector<glm::vec3> px(healpix::pixelCount(order), glm::vec3(background));
  if (blackHalf)
    for (size_t p = 0; p < px.size() / 2; ++p) px[p] = glm::vec3(0.0f);
  Environment probe = constantEnvironment(order, glm::vec3(1.0f));
  px[probe.pixelOf(kSunDir)] = glm::vec3(2000.0f, 1800.0f, 1500.0f);
  return environmentFromPixels(order, std::move(px));
}

// Two-sided normal quantile for the z-test: z such that P(|Z| > z) = alpha.
inline double normalQuantileTwoSided(double alpha) {
  // Bisection on erfc: robust and plenty fast for a handful of calls.
  double lo = 0.0, hi = 40.0;
  for (int i = 0; i < 200; ++i) {
    double mid = 0.5 * (lo + hi);
    (std::erfc(mid / std::sqrt(2.0)) > alpha ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

inline Material lambert(float albedo) {
  Material m;
  m.type = MaterialType::Lambert;
  m.diffuse = glm::vec3(albedo);
  return m;
}

inline Material ggx(float alpha, glm::vec3 f0, glm::vec3 diffuse = glm::vec3(0.0f)) {
  Material m;
  m.type = MaterialType::Ggx;
  m.alpha = alpha;
  m.specular = f0;
  m.diffuse = diffuse;
  return m;
}

inline Material phong(float exponent, glm::vec3 ks, glm::vec3 diffuse = glm::vec3(0.0f)) {
  Material m;
  m.type = MaterialType::Phong;
  m.exponent = exponent;
  m.specular = ks;
  m.diffuse = diffuse;
  return m;
}

// A shading point at the origin on the plane y = 0 (normal +y), lit by `env`,
// optionally shadowed by spheres.
struct ShadingSetup {
  std::string name;
  Scene scene;
  ShadingPoint sp;
};

inline ShadingSetup makeSetup(std::string name, Environment env, Material material, glm::vec3 wo,
                       std::vector<Sphere> occluders = {}) {
  ShadingSetup s;
  s.name = std::move(name);
  s.scene.materials = {material, lambert(0.5f)};
  for (Sphere& o : occluders) o.material = 1;
  s.scene.spheres = std::move(occluders);
  s.scene.planes = {{glm::vec3(0.0f), glm::vec3(0, 1, 0), 0}};
  s.scene.environment = std::move(env);
  s.sp = {glm::vec3(0.0f), glm::vec3(0, 1, 0), glm::normalize(wo), nullptr};
  return s;
}

// The exact integral of the piecewise-constant environment against f cos V,
// each pixel's share integrated on a sub x sub grid of area-uniform points.
inline glm::dvec3 bruteForceIntegral(const ShadingSetup& s, int sub) {
  const Environment& env = s.scene.environment;
  ShadingPoint sp = s.sp;
  sp.material = &s.scene.materials[0];
  tbb::combinable<glm::dvec3> partial([] { return glm::dvec3(0.0); });
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, env.radiance.size()), [&](const auto& r) {
    glm::dvec3& acc = partial.local();
    for (uint64_t p = r.begin(); p != r.end(); ++p) {
      if (env.radiance[p] == glm::vec3(0.0f)) continue;
      glm::dvec3 sum(0.0);
      for (int j = 0; j < sub; ++j)
        for (int i = 0; i < sub; ++i) {
          glm::vec3 wi = env.direction(env.order, p, (i + 0.5f) / sub, (j + 0.5f) / sub);
          sum += glm::dvec3(visibleReflectance(s.scene, sp, wi));
        }
      acc += sum * glm::dvec3(env.radiance[p]) * (env.pixelSolidAngle() / (sub * sub));
    }
  });
  return partial.combine([](glm::dvec3 a, glm::dvec3 b) { return a + b; });
}

struct MeanAndError {
  glm::dvec3 mean;
  glm::dvec3 stdError;
  double luminanceVariance = 0.0;  // of one estimate
};

// The tables an HtPoint with these options reads.
inline MethodTables htTables(const Scene& scene, const HtOptions& options) {
  MethodOptions mo;
  mo.brdfBounds = options.brdfTable ? MethodOptions::BrdfBounds::Table : MethodOptions::BrdfBounds::Analytic;
  return prepareTables(scene, Method::Ht, mo);
}

// `batches` independent estimates of `spp` samples each, streams 0..batches-1.
inline MeanAndError repeatedEstimates(const ShadingSetup& s, Method method, int batches, int spp, uint32_t seed,
                                      const MethodOptions& options = {}) {
  ShadingPoint sp = s.sp;
  sp.material = &s.scene.materials[0];
  struct Acc {
    glm::dvec3 sum{0.0}, sumSq{0.0};
    double lumSum = 0.0, lumSq = 0.0;
  };
  tbb::combinable<Acc> partial;
  const MethodTables tables = prepareTables(s.scene, method, options);
  tbb::parallel_for(tbb::blocked_range<int>(0, batches), [&](const auto& r) {
    Acc& a = partial.local();
    EstimateCounters counters;
    for (int b = r.begin(); b != r.end(); ++b) {
      Rng rng(seed, uint32_t(b));
      glm::dvec3 e(estimateDirect(s.scene, sp, method, spp, rng, counters, tables, options));
      a.sum += e;
      a.sumSq += e * e;
      double y = luminance(glm::vec3(e));
      a.lumSum += y;
      a.lumSq += y * y;
    }
  });
  Acc total;
  partial.combine_each([&](const Acc& a) {
    total.sum += a.sum;
    total.sumSq += a.sumSq;
    total.lumSum += a.lumSum;
    total.lumSq += a.lumSq;
  });
  MeanAndError r;
  double n = batches;
  r.mean = total.sum / n;
  glm::dvec3 var = glm::max(glm::dvec3(0.0), (total.sumSq / n - r.mean * r.mean) * (n / (n - 1.0)));
  r.stdError = glm::sqrt(var / n);
  r.luminanceVariance = std::max(0.0, (total.lumSq / n - (total.lumSum / n) * (total.lumSum / n)) * (n / (n - 1.0)));
  return r;
}

// The setup's point on a flat surface (points nearby share its normal).
inline ShadingSetup flat(ShadingSetup s) {
  s.sp.flat = true;
  return s;
}

#ifdef HT_TEST_DATA
// sunriseAt(order), read once per order.
inline const Environment& sunriseCached(int order) {
  static std::map<int, Environment> maps;
  if (!maps.count(order)) maps.emplace(order, sunriseAt(order));
  return maps.at(order);
}

// Shading points that take each path of the fixed-count product methods
// (ht-frontier, ht-cut), under sunrise.exr and a one-pixel sun at 2^order:
// flat and curved diffuse points with and without occluders, glossy points
// with both lobes and with a lobe alone (conductors) down to GGX alpha
// 0.01, a grazing view on a flat glossy surface, a conductor mirroring the sun.
inline std::vector<ShadingSetup> productSetups(int order) {
  const Environment& sunrise = sunriseCached(order);
  std::vector<ShadingSetup> s;
  s.push_back(flat(makeSetup("flat-diffuse-sunrise-occluded", sunrise, lambert(0.8f), {0.3f, 1.0f, 0.2f},
                             {{glm::vec3(-1.0f, 1.0f, 0.5f), 0.8f, 0}, {glm::vec3(1.5f, 0.4f, -0.3f), 0.4f, 0}})));
  s.push_back(makeSetup("diffuse-sunrise", sunrise, lambert(0.8f), {0.3f, 1.0f, 0.2f}));
  s.push_back(makeSetup("ggx0.05-sunrise", sunrise, ggx(0.05f, glm::vec3(0.9f, 0.7f, 0.4f)), {0.2f, 0.5f, -0.8f}));
  s.push_back(makeSetup("phong-sunrise-occluded", sunrise, phong(40.0f, glm::vec3(0.4f), glm::vec3(0.3f)),
                        {-0.4f, 0.6f, 0.3f}, {{glm::vec3(-1.0f, 1.0f, 0.5f), 0.8f, 0}}));
  s.push_back(flat(makeSetup("flat-diffuse-sun-shadowed", onePixelSun(order), lambert(0.8f), {0.0f, 1.0f, 0.3f},
                             {{2.0f * kSunDir, 0.4f, 0}})));
  s.push_back(makeSetup("ggx0.3-sun", onePixelSun(order), ggx(0.3f, glm::vec3(0.04f), glm::vec3(0.5f)),
                        mirrorOf(kSunDir)));
  s.push_back(makeSetup("ggx0.01-sunrise", sunrise, ggx(0.01f, glm::vec3(0.95f)), {0.3f, 0.6f, -0.5f}));
  s.push_back(flat(makeSetup("flat-ggx0.05-plastic-grazing-sunrise-occluded", sunrise,
                             ggx(0.05f, glm::vec3(0.04f), glm::vec3(0.3f)), {0.1f, 0.06f, 1.0f},
                             {{glm::vec3(0.0f, 0.4f, -1.0f), 0.4f, 0}})));
  s.push_back(flat(makeSetup("flat-ggx0.1-conductor-sun", onePixelSun(order), ggx(0.1f, glm::vec3(0.9f)),
                             mirrorOf(kSunDir))));
  return s;
}
#endif

// Every setup's mean over `batches` estimates of n directions by `method`,
// for each n in `counts`, against the brute force on a sub x sub grid per
// pixel (its error taken from the grid of half the size): z-tests
// Sidak-corrected over setups, counts and channels.
inline void expectUnbiasedAgainstBruteForce(const std::vector<ShadingSetup>& all, Method method,
                                            const std::vector<int>& counts, int batches, uint32_t seedBase, int sub) {
  const int tests = int(all.size() * counts.size() * 3);
  const double zCrit = normalQuantileTwoSided(1.0 - std::pow(1.0 - 0.01, 1.0 / tests));
  for (const ShadingSetup& s : all) {
    const glm::dvec3 ref = bruteForceIntegral(s, sub);
    const glm::dvec3 refError = glm::abs(ref - bruteForceIntegral(s, sub / 2));
    for (int n : counts) {
      const MeanAndError e = repeatedEstimates(s, method, batches, n, seedBase + uint32_t(n));
      for (int c = 0; c < 3; ++c) {
        const double se = std::sqrt(e.stdError[c] * e.stdError[c] + refError[c] * refError[c]);
        ASSERT_GT(se, 0.0) << s.name;
        EXPECT_LT(std::abs(e.mean[c] - ref[c]) / se, zCrit)
            << s.name << " n " << n << " channel " << c << ": mean " << e.mean[c] << " reference " << ref[c];
      }
    }
  }
}

}  // namespace ht::test
