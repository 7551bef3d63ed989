// restir and restir-biased (host/restir.h) on the CPU reference: what they
// share with ris, exact counts, independence from the thread count, and
// unbiasedness of the image against mis over many seeds.
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "error.h"
#include "estimator_harness.h"
#include "integrator.h"
#include "render.h"
#include "restir.h"

namespace ht {
namespace {

using test::normalQuantileTwoSided;

Scene smallScene(const std::string& path, int nside) {
  Scene s = readSceneFile(path);
  s.environmentDesc.nside = nside;
  loadEnvironment(s);
  return s;
}

const Scene& spheres() {
  static const Scene s = smallScene(std::string(HT_TEST_DATA) + "/scenes/spheres.json", 16);
  return s;
}

RenderSettings restirSettings(Method m, int spp, uint32_t seed, int width = 24, int height = 12) {
  RenderSettings s;
  s.method = m;
  s.spp = spp;
  s.seed = seed;
  s.width = width;
  s.height = height;
  s.options.risCandidates = 8;
  s.options.restirRadius = 6;
  return s;
}

double lum(const glm::vec3& c) { return (double(c.x) + double(c.y) + double(c.z)) / 3.0; }

// With no rounds restir is ris: the same draws, W rounded to a float.
TEST(Restir, NoRoundsIsRis) {
  RenderSettings s = restirSettings(Method::Restir, 8, 3);
  s.options.restirRounds = 0;
  s.pixelCounts = true;
  const RenderResult a = renderCpu(spheres(), s);
  s.method = Method::Ris;
  const RenderResult b = renderCpu(spheres(), s);
  EXPECT_EQ(a.counters.directions, b.counters.directions);
  EXPECT_EQ(a.counters.shadowRays, b.counters.shadowRays);
  EXPECT_EQ(a.pixelDirections, b.pixelDirections);
  for (size_t i = 0; i < a.image.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c)
      ASSERT_NEAR(a.image.pixels[i][c], b.image.pixels[i][c], 1e-5f * b.image.pixels[i][c] + 1e-9f) << i;
}

// Each shaded pixel draws M candidates per chain; the unbiased variant
// traces one shadow ray per chain at most, the biased one two.
TEST(Restir, CountsAreExact) {
  for (Method m : {Method::Restir, Method::RestirBiased}) {
    RenderSettings s = restirSettings(m, 5, 2);
    s.pixelCounts = true;
    const RenderResult r = renderCpu(spheres(), s);
    ASSERT_GT(r.shadedPixels, 0u);
    uint64_t shaded = 0;
    for (uint32_t d : r.pixelDirections) {
      EXPECT_TRUE(d == 0 || d == 5 * 8) << d;
      shaded += d > 0;
    }
    EXPECT_EQ(shaded, r.shadedPixels);
    EXPECT_EQ(r.counters.directions, r.shadedPixels * 5 * 8);
    EXPECT_LE(r.counters.shadowRays, r.shadedPixels * 5 * (m == Method::Restir ? 1 : 2));
    EXPECT_GT(r.counters.shadowRays, r.shadedPixels);
  }
}

TEST(Restir, OneThreadGivesTheSameImage) {
  for (Method m : {Method::Restir, Method::RestirBiased}) {
    const RenderSettings s = restirSettings(m, 4, 9, 40, 20);
    const RenderResult many = renderCpu(spheres(), s);
    RenderResult one;
    {
      tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
      one = renderCpu(spheres(), s);
    }
    EXPECT_EQ(one.image.pixels, many.image.pixels) << methodName(m);
    EXPECT_EQ(one.counters.shadowRays, many.counters.shadowRays);
  }
}

TEST(Restir, BlackEnvironmentIsZeroAndPointsAreRefused) {
  Scene scene = spheres();
  scene.environment = constantEnvironment(2, glm::vec3(0.0f));
  for (Method m : {Method::Restir, Method::RestirBiased}) {
    const RenderResult r = renderCpu(scene, restirSettings(m, 4, 1));
    for (const glm::vec3& p : r.image.pixels) ASSERT_EQ(p, glm::vec3(0.0f)) << methodName(m);
    EXPECT_EQ(r.counters.shadowRays, 0u);
    Rng rng(1, 1);
    EstimateCounters c;
    const MethodTables tables;
    const ShadingPoint sp{glm::vec3(0.0f), glm::vec3(0, 1, 0), glm::vec3(0, 1, 0), &scene.materials[0], false};
    EXPECT_THROW(estimateDirect(scene, sp, m, 4, rng, c, tables), Error);
  }
}

// The mean over `seeds` renders of each pixel's luminance, and its standard error.
struct PixelStats {
  std::vector<double> mean, error;
  double imageMean = 0.0, imageError = 0.0;
};
PixelStats seedStats(const Scene& scene, RenderSettings s, int seeds, uint32_t firstSeed) {
  const size_t n = size_t(s.width) * s.height;
  std::vector<double> sum(n, 0.0), sum2(n, 0.0);
  double isum = 0.0, isum2 = 0.0;
  for (int k = 0; k < seeds; ++k) {
    s.seed = firstSeed + uint32_t(k);
    const RenderResult r = renderCpu(scene, s);
    double image = 0.0;
    for (size_t i = 0; i < n; ++i) {
      const double v = lum(r.image.pixels[i]);
      sum[i] += v;
      sum2[i] += v * v;
      image += v;
    }
    image /= double(n);
    isum += image;
    isum2 += image * image;
  }
  PixelStats st;
  st.mean.resize(n);
  st.error.resize(n);
  for (size_t i = 0; i < n; ++i) {
    st.mean[i] = sum[i] / seeds;
    st.error[i] = std::sqrt(std::max(0.0, sum2[i] / seeds - st.mean[i] * st.mean[i]) / (seeds - 1));
  }
  st.imageMean = isum / seeds;
  st.imageError = std::sqrt(std::max(0.0, isum2 / seeds - st.imageMean * st.imageMean) / (seeds - 1));
  return st;
}

// restir's pixels and image mean over many seeds agree with mis's by
// z-tests (Sidak over the pixels); restir-biased's deviation is printed.
void expectUnbiased(const Scene& scene, const std::string& name, int width, int height, int seeds) {
  RenderSettings ref = restirSettings(Method::Mis, 64, 0, width, height);
  const PixelStats m = seedStats(scene, ref, seeds, 1000);
  RenderSettings s = restirSettings(Method::Restir, 4, 0, width, height);
  const PixelStats r = seedStats(scene, s, seeds, 1);
  s.method = Method::RestirBiased;
  const PixelStats b = seedStats(scene, s, seeds, 1);
  const size_t n = m.mean.size();
  const double zCrit = normalQuantileTwoSided(1.0 - std::pow(1.0 - 0.01, 1.0 / double(n + 1)));
  size_t failed = 0, unjudged = 0;
  double worst = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const double se = std::hypot(m.error[i], r.error[i]);
    if (se == 0.0) {
      EXPECT_EQ(m.mean[i], r.mean[i]) << name << " pixel " << i;
      continue;
    }
    // A pixel lit only by a dim sky next to a blocked sun that is 1e4
    // times brighter: the sun wins every reservoir, and a sky sample, rare
    // and then heavy, may never be drawn in all the chains, which leaves no
    // spread to test against. Such pixels must be dim.
    if (r.error[i] == 0.0 && r.mean[i] == 0.0) {
      ++unjudged;
      EXPECT_LT(m.mean[i], 1e-3 * m.imageMean) << name << " pixel " << i;
      continue;
    }
    const double z = std::abs(r.mean[i] - m.mean[i]) / se;
    worst = std::max(worst, z);
    failed += z > zCrit;
  }
  const double zImage = std::abs(r.imageMean - m.imageMean) / std::hypot(m.imageError, r.imageError);
  const double zBiased = std::abs(b.imageMean - m.imageMean) / std::hypot(m.imageError, b.imageError);
  std::printf("[ restir   ] %-22s %zu px, %d seeds: worst pixel z %.2f (critical %.2f, %zu dark pixels never "
              "lit), image mean z %.2f; restir-biased image mean %+.2f %% (z %.1f)\n",
              name.c_str(), n, seeds, worst, zCrit, unjudged, zImage, 100.0 * (b.imageMean / m.imageMean - 1.0),
              zBiased);
  EXPECT_EQ(failed, 0u) << name;
  EXPECT_LT(zImage, zCrit) << name;
}

TEST(Restir, UnbiasedOnSpheres) { expectUnbiased(spheres(), "spheres", 32, 16, 1000); }

TEST(RestirSlow, UnbiasedOnStressScenes) {
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(std::string(HT_TEST_DATA) + "/scenes/stress"))
    if (e.path().extension() == ".json") files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  ASSERT_GE(files.size(), 8u);
  for (const std::string& f : files)
    expectUnbiased(smallScene(f, 16), std::filesystem::path(f).stem().string(), 24, 12, 400);
}

}  // namespace
}  // namespace ht
