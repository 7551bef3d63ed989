// Hierarchical thresholding: the traversal against a full scan, its density,
// its sample count, its bounds, and the unbiasedness of its estimates.
#include <gtest/gtest.h>

#include <map>
#include <random>
#include <set>

#include <glm/geometric.hpp>

#include "chi2.h"
#include "estimator_harness.h"
#include "ht.h"
#include "image_io.h"

using namespace ht;
using namespace ht::test;

namespace {

// Sky with a sun pixel and a black lower half, at a small resolution.
Environment smallSky(int order) {
  std::vector<glm::vec3> px(healpix::pixelCount(order));
  Environment probe = constantEnvironment(order, glm::vec3(1.0f));
  for (uint64_t p = 0; p < px.size(); ++p) {
    glm::vec3 d = probe.direction(order, p, 0.5f, 0.5f);
    px[p] = d.y > 0.0f ? glm::vec3(0.3f, 0.5f, 0.9f) * (0.5f + d.y) : glm::vec3(0.0f);
  }
  px[probe.pixelOf(kSunDir)] = glm::vec3(3000.0f, 2500.0f, 2000.0f);
  return environmentFromPixels(order, std::move(px), 20.0f);
}


std::vector<ShadingSetup> smallSetups(int order) {
  std::vector<ShadingSetup> s;
  s.push_back(makeSetup("glossy-sun", smallSky(order), ggx(0.2f, glm::vec3(0.9f)), mirrorOf(kSunDir)));
  s.push_back(makeSetup("diffuse-shadowed", smallSky(order), lambert(0.7f), {0.2f, 1.0f, 0.1f},
                        {{1.5f * kSunDir, 0.3f, 0}, {glm::vec3(-1.0f, 0.5f, 0.0f), 0.6f, 0}}));
  s.push_back(makeSetup("phong-grazing", smallSky(order), phong(60.0f, glm::vec3(0.5f), glm::vec3(0.2f)),
                        {std::sin(1.45f), std::cos(1.45f), 0.2f}));
  return s;
}

HtOptions optionsFor(bool visibility, bool table = false) {
  HtOptions o;
  o.visibility = visibility;
  o.brdfTable = table;
  return o;
}

// Accepted candidates per leaf by scanning every leaf: r from the digit
// permutations on its path, h from the leaf's value, all i = r + k 4^D with
// i + u < T(h).
std::map<uint64_t, std::multiset<uint64_t>> fullScan(const HtPoint& ht, uint32_t seed, float u) {
  std::map<uint64_t, std::multiset<uint64_t>> accepted;
  const int D = ht.env.order;
  for (uint64_t leaf = 0; leaf < healpix::pixelCount(D); ++leaf) {
    float h = ht.leafValue(leaf, ht.pathBound(leaf));
    if (h <= 0.0f) continue;
    double t = ht.threshold(h);
    uint64_t r = ht.lowestCandidate(seed, D, leaf);
    for (uint64_t i = r; double(i) + u < t; i += ht.stride(D)) accepted[leaf].insert(i);
  }
  return accepted;
}

// One traversal with the pixel seed, offset and jitter that run `run` of
// `stream` draws; `samples` receives its samples.
void traverseRun(const HtPoint& ht, uint32_t run, uint32_t stream, std::vector<HtSample>& samples) {
  Rng rng(run, stream);
  samples.clear();
  HtCounters counters;
  const uint32_t seed = rng.nextUint();
  const float u = rng.next();
  PixelSampler jitter(SamplerKind::Stratified, rng.nextUint());
  ht.traverse(seed, u, jitter, samples, counters);
}

}  // namespace

// Pruning never loses a candidate: the traversal accepts exactly what a scan
// of all leaves accepts, for the same seed and offset.
TEST(Ht, TraversalAcceptsExactlyTheFullScan) {
  for (int order : {2, 4}) {
    for (const ShadingSetup& s : smallSetups(order)) {
      for (int variant = 0; variant < 8; ++variant) {
        bool vis = variant & 1, table = variant & 2;
        HtOptions opt = optionsFor(vis, table);
        opt.sphereSequence = variant & 4;
        ShadingPoint sp = s.sp;
        sp.material = &s.scene.materials[0];
        const MethodTables tables = htTables(s.scene, opt);
        HtPoint ht(s.scene, sp, opt, tables);
        for (double n : {4.0, 64.0, 1024.0}) {
          ht.setBudget(n);
          for (uint32_t seed = 1; seed <= 3; ++seed) {
            Rng rng(seed, 77);
            float u = rng.next();
            std::vector<HtSample> samples;
            HtCounters counters;
            PixelSampler jitter(SamplerKind::Stratified, rng.nextUint());
            ht.traverse(seed, u, jitter, samples, counters);
            std::map<uint64_t, std::multiset<uint64_t>> got;
            for (const HtSample& x : samples) got[x.pixel].insert(x.candidate);
            auto want = fullScan(ht, seed, u);
            ASSERT_EQ(got, want) << s.name << " order " << order << " vis " << vis << " table " << table
                                 << " sphere sequence " << opt.sphereSequence << " n " << n << " seed " << seed;
            EXPECT_LT(counters.nodes, MaxAvgTree::levelOffset(order + 1)) << "nothing was pruned";
          }
        }
      }
    }
  }
}

// The samples' density is s h: chi-square over bins one level finer than the
// leaves (so the jitter inside a leaf is tested too), Sidak over the cases.
TEST(Ht, DensityIsProportionalToH) {
  const int order = 3;
  std::vector<ShadingSetup> setups = smallSetups(order);
  const double alpha = sidakAlpha(0.01, int(setups.size()) * 2);
  for (const ShadingSetup& s : setups) {
    for (bool vis : {false, true}) {
      HtOptions opt = optionsFor(vis);
      ShadingPoint sp = s.sp;
      sp.material = &s.scene.materials[0];
      const MethodTables tables = htTables(s.scene, opt);
      HtPoint ht(s.scene, sp, opt, tables);
      ht.setBudget(32.0);
      const int binOrder = order + 1;
      std::vector<double> expected(healpix::pixelCount(binOrder), 0.0);
      std::vector<uint64_t> observed(expected.size(), 0);
      const int runs = 20000;
      for (uint64_t leaf = 0; leaf < healpix::pixelCount(order); ++leaf) {
        double perLeaf = runs * ht.scale() * ht.leafValue(leaf, ht.pathBound(leaf)) * healpix::pixelSolidAngle(order);
        for (uint64_t c = 4 * leaf; c < 4 * leaf + 4; ++c) expected[c] = perLeaf / 4.0;
      }
      std::vector<HtSample> samples;
      for (int run = 0; run < runs; ++run) {
        traverseRun(ht, uint32_t(1000 + run), 5, samples);
        for (const HtSample& x : samples) ++observed[binIndex(binOrder, s.scene.environment.toHealpixFrame(x.dir))];
      }
      Chi2Result r = chi2Test(observed, expected);
      EXPECT_GT(r.pValue, alpha) << s.name << " vis " << vis << ": " << describe(r, observed, expected);
    }
  }
}

// E[count] = n C / C_est, with C the exact integral of h (z-test).
TEST(Ht, ExpectedSampleCount) {
  const int order = 3;
  int tests = 0;
  std::vector<std::pair<std::string, double>> zs;
  for (const ShadingSetup& s : smallSetups(order)) {
    for (bool vis : {false, true}) {
      HtOptions opt = optionsFor(vis);
      ShadingPoint sp = s.sp;
      sp.material = &s.scene.materials[0];
      const MethodTables tables = htTables(s.scene, opt);
      HtPoint ht(s.scene, sp, opt, tables);
      double c = 0.0;
      for (uint64_t leaf = 0; leaf < healpix::pixelCount(order); ++leaf)
        c += double(ht.leafValue(leaf, ht.pathBound(leaf))) * healpix::pixelSolidAngle(order);
      for (double n : {4.0, 64.0}) {
        ht.setBudget(n);
        const int runs = 5000;
        double sum = 0.0, sumSq = 0.0;
        std::vector<HtSample> samples;
        for (int run = 0; run < runs; ++run) {
          traverseRun(ht, uint32_t(run), 9, samples);
          sum += double(samples.size());
          sumSq += double(samples.size()) * double(samples.size());
        }
        double mean = sum / runs, var = (sumSq / runs - mean * mean) * runs / (runs - 1.0);
        double expected = n * c / ht.budgetEstimate();
        zs.push_back({s.name + (vis ? " vis" : "") + " n=" + std::to_string(int(n)),
                      (mean - expected) / std::sqrt(var / runs + 1e-300)});
        ++tests;
        // The budget estimate itself keeps the count near n.
        EXPECT_GT(mean, 0.25 * n) << s.name;
        EXPECT_LT(mean, 4.0 * n) << s.name;
      }
    }
  }
  const double zCrit = normalQuantileTwoSided(sidakAlpha(0.01, tests));
  for (const auto& [name, z] : zs) EXPECT_LT(std::abs(z), zCrit) << name;
}

// For random nodes and directions inside them, the product never exceeds
// the bound used to prune, and a node classified as blocked is blocked.
TEST(Ht, BoundsAreConservative) {
  const int order = 5;
  std::vector<ShadingSetup> setups = smallSetups(order);
  setups.push_back(makeSetup("mirror-like", smallSky(order), ggx(0.02f, glm::vec3(0.95f)), mirrorOf(kSunDir)));
  setups.push_back(makeSetup("phong-1000", smallSky(order), phong(1000.0f, glm::vec3(0.9f)), {0.3f, 0.8f, 0.1f}));
  std::mt19937_64 gen(42);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (int variant = 0; variant < 2 * int(setups.size()); ++variant) {
    const ShadingSetup& s = setups[variant / 2];
    const bool table = variant & 1;
    ShadingPoint sp = s.sp;
    sp.material = &s.scene.materials[0];
    HtOptions opt = optionsFor(true, table);
    const MethodTables tables = htTables(s.scene, opt);
    HtPoint ht(s.scene, sp, opt, tables);
    const Environment& env = s.scene.environment;
    int blockedChecked = 0;
    for (int trial = 0; trial < 3000; ++trial) {
      int level = int(gen() % (order + 1));
      uint64_t node = gen() % healpix::pixelCount(level);
      // Bias half the trials towards the lobe, where bounds are tight.
      if (trial % 2 == 0) node = healpix::vecToPix(level, glm::dvec3(ht.mirror));
      float b = ht.bound(level, node);
      const glm::vec3& c = ht.geometry.centers[MaxAvgTree::levelOffset(level) + node];
      float brdfB = ht.brdfBound(MaxAvgTree::levelOffset(level) + node);
      int cls = ht.visibilityClass(c, level);
      for (int k = 0; k < 50; ++k) {
        double dx = k < 4 ? double(k & 1) : uni(gen), dy = k < 4 ? double(k >> 1) : uni(gen);
        glm::dvec3 hp = healpix::pixToVec(level, node, dx, dy);
        glm::vec3 w = env.fromHealpixFrame(hp);
        uint64_t leaf = healpix::vecToPix(order, hp);
        float exactBrdf = luminance(evalBsdf(*sp.material, ht.woLocal, ht.frame.toLocal(glm::vec3(hp))));
        ASSERT_LE(exactBrdf, brdfB * (1.0f + 1e-4f) + 1e-12f)
            << s.name << (table ? " table" : " analytic") << " level " << level << " node " << node;
        if (k < 4) continue;  // corners may fall in a neighbouring leaf
        bool visible = !occluded(s.scene, offsetRayOrigin(sp.position, sp.normal), w);
        float product = luminance(env.radiance[leaf]) * exactBrdf * (visible ? 1.0f : 0.0f);
        ASSERT_LE(product, b * (1.0f + 1e-4f) + 1e-12f)
            << s.name << (table ? " table" : " analytic") << " level " << level << " node " << node;
        if (cls == 0) {
          ASSERT_FALSE(visible) << s.name << ": node classified blocked sees the sky";
          ++blockedChecked;
        }
      }
    }
    if (s.name == "diffuse-shadowed") {
      EXPECT_GT(blockedChecked, 0);
    }
  }
}

// Every node of a level lies within the level's radius of its centre.
TEST(Ht, LevelRadiusBoundsEveryNode) {
  const std::shared_ptr<const HtGeometry> geometry = buildHtGeometry(6);
  const HtGeometry& g = *geometry;
  std::mt19937_64 gen(3);
  for (int level = 0; level <= healpix::kMaxOrder; ++level) {
    std::vector<uint64_t> pixels;
    uint64_t n = healpix::pixelCount(level);
    for (int f = 0; f < 12; ++f) {  // face corners and centres are the most distorted
      uint64_t side = uint64_t(1) << level;
      for (uint32_t ix : {uint32_t(0), uint32_t(side - 1), uint32_t(side / 2)})
        for (uint32_t iy : {uint32_t(0), uint32_t(side - 1), uint32_t(side / 2)})
          pixels.push_back(healpix::xyfToPix(level, ix, iy, f));
    }
    for (int k = 0; k < 2000; ++k) pixels.push_back(gen() % n);
    for (uint64_t p : pixels) {
      double r = healpix::boundingCone(level, p).radius;
      ASSERT_LE(r, double(g.levelRadius[level])) << "level " << level;
      if (level <= g.order) {
        glm::vec2 cs = g.cosSinRadius[MaxAvgTree::levelOffset(level) + p];
        ASSERT_LE(r, std::atan2(double(cs.y), double(cs.x)) * (1.0 + 1e-6)) << "level " << level << " pixel " << p;
      }
    }
  }
}

// visibilityClass tests the caps four at a time where it can; with 1, 3,
// 5, 7 (one or two groups of lanes) and 11 caps (the plain loop) it gives
// the class the caps' own thresholds give, at every level.
TEST(Ht, VisibilityClassAgreesWithTheCaps) {
  const int order = 4;
  std::mt19937_64 gen(7);
  std::uniform_real_distribution<float> uni(-1.0f, 1.0f);
  for (int spheres : {0, 2, 4, 6, 10}) {
    std::vector<Sphere> occluders;
    for (int k = 0; k < spheres; ++k) {
      const glm::vec3 d = glm::normalize(glm::vec3(uni(gen), 0.3f + std::abs(uni(gen)), uni(gen)));
      occluders.push_back({(1.2f + 2.0f * std::abs(uni(gen))) * d, 0.2f + 0.4f * std::abs(uni(gen)), 0});
    }
    const ShadingSetup s = makeSetup("caps", smallSky(order), lambert(0.7f), {0.2f, 1.0f, 0.1f}, occluders);
    ShadingPoint sp = s.sp;
    sp.material = &s.scene.materials[0];
    const HtOptions opt = optionsFor(true);
    const MethodTables tables = htTables(s.scene, opt);
    const HtPoint ht(s.scene, sp, opt, tables);
    ASSERT_EQ(ht.caps.size(), size_t(spheres + 1));  // and the plane's
    int seen[3] = {0, 0, 0};
    for (int level = 0; level <= order; ++level)
      for (uint64_t p = 0; p < healpix::pixelCount(level); ++p) {
        const glm::vec3& c = ht.geometry.centers[MaxAvgTree::levelOffset(level) + p];
        int expected = 1;
        for (const Cap& cap : ht.caps) {
          const float d = glm::dot(c, cap.axis);
          if (d >= cap.cosInside[level]) {
            expected = 0;
            break;
          }
          if (d > cap.cosOutside[level]) expected = 2;
        }
        ASSERT_EQ(ht.visibilityClass(c, level), expected) << spheres << " spheres, level " << level << " node " << p;
        ++seen[expected];
      }
    EXPECT_GT(seen[0], 0) << spheres;
    EXPECT_GT(seen[1], 0) << spheres;
    EXPECT_GT(seen[2], 0) << spheres;
  }
}

// The traversal's packed node records hold the geometry's and the trees'
// values unchanged, and an HtPoint refuses records of another map.
TEST(Ht, NodeRecordsPackGeometryAndTrees) {
  const int order = 3;
  const ShadingSetup s = smallSetups(order)[0];
  const std::shared_ptr<const HtGeometry> g = buildHtGeometry(order);
  const std::shared_ptr<const HtNodes> nodes = buildHtNodes(*g, s.scene.environment.tree);
  ASSERT_EQ(nodes->count, g->centers.size());
  for (size_t i = 0; i < nodes->count; ++i) {
    const HtNode& n = nodes->data()[i];
    ASSERT_EQ(n.centre, g->centers[i]) << i;
    ASSERT_EQ(n.cosSinRadius, g->cosSinRadius[i]) << i;
    ASSERT_EQ(n.maxv, s.scene.environment.tree.maxv[i]) << i;
    ASSERT_EQ(n.avgv, s.scene.environment.tree.avgv[i]) << i;
  }
  // Each record's hash gives the permutation the node's level and index do.
  for (int level = 0; level <= order; ++level)
    for (uint64_t p = 0; p < MaxAvgTree::levelSize(level); ++p)
      for (uint32_t seed : {0u, 7u, 0x9e3779b9u})
        ASSERT_EQ(HtPoint::permutationOf(seed, nodes->data()[MaxAvgTree::levelOffset(level) + p].hash),
                  HtPoint::permutation(seed, level, p))
            << "level " << level << " node " << p;
  EXPECT_THROW(buildHtNodes(*buildHtGeometry(order + 1), s.scene.environment.tree), Error);

  const HtOptions opt = optionsFor(true);
  const MethodTables tables = htTables(s.scene, opt);
  Scene other = s.scene;
  other.environment = smallSky(order);  // the same values, another tree
  ShadingPoint sp = s.sp;
  sp.material = &other.materials[0];
  EXPECT_THROW(HtPoint(other, sp, opt, tables), Error);
  const MethodTables own = htTables(other, opt);
  EXPECT_NO_THROW(HtPoint(other, sp, opt, own));
}

// ht and ht-vis are unbiased: z-tests against the brute-force integral at
// the shading points of the baseline tests and a black hemisphere.
// Hit points round to either side of their surface. The visibility caps
// must not see a point rounded to just below its own plane, or just inside
// its own sphere, as blocked from the sky: white furnace, Lambert 0.8, the
// estimate stays 0.8 on both sides.
TEST(Ht, VisibilityCapsIgnoreRoundingAcrossTheOwnSurface) {
  for (float dy : {0.0f, -1e-6f, 1e-6f}) {
    ShadingSetup s = makeSetup("furnace", constantEnvironment(4, glm::vec3(1.0f)), lambert(0.8f), {0.3f, 1.0f, 0.2f});
    s.sp.position.y = dy;
    s.sp.material = &s.scene.materials[0];
    Rng rng(5, 1);
    PixelSampler sampler(SamplerKind::Stratified, 5);
    EstimateCounters counters;
    glm::vec3 e = estimateHt(s.scene, s.sp, optionsFor(true), 64, 77, rng, sampler, counters,
                             htTables(s.scene, optionsFor(true)));
    EXPECT_NEAR(e.g, 0.8f, 0.1f) << "plane, dy = " << dy;
  }
  // A point on a sphere's top, rounded into it.
  ShadingSetup s = makeSetup("furnace", constantEnvironment(4, glm::vec3(1.0f)), lambert(0.8f), {0.3f, 1.0f, 0.2f},
                             {{glm::vec3(0.0f, 1.0f, 0.0f), 1.0f, 0}});
  s.scene.planes.clear();
  s.sp.position = glm::vec3(0.0f, 2.0f - 1e-6f, 0.0f);
  s.sp.material = &s.scene.materials[0];
  Rng rng(6, 1);
  PixelSampler sampler(SamplerKind::Stratified, 6);
  EstimateCounters counters;
  glm::vec3 e = estimateHt(s.scene, s.sp, optionsFor(true), 64, 78, rng, sampler, counters,
                           htTables(s.scene, optionsFor(true)));
  EXPECT_NEAR(e.g, 0.8f, 0.1f) << "sphere";
}

TEST(Ht, UnbiasedAgainstBruteForce) {
  const int order = 5;
  std::vector<ShadingSetup> setups;
  setups.push_back(makeSetup("glossy-small-sun", smallSky(order), ggx(0.1f, glm::vec3(0.9f)), mirrorOf(kSunDir)));
  setups.push_back(makeSetup("sun-shadow", smallSky(order), lambert(0.8f), {0.0f, 1.0f, 0.3f},
                             {{2.0f * kSunDir, 0.4f, 0}}));
  setups.push_back(makeSetup("grazing-sunrise", sunriseAt(order), ggx(0.25f, glm::vec3(0.95f)),
                             {std::sin(1.48f), std::cos(1.48f), 0.0f}));
  setups.push_back(makeSetup("phong-sunrise-occluded", sunriseAt(order), phong(40.0f, glm::vec3(0.4f), glm::vec3(0.3f)),
                             {-0.4f, 0.6f, 0.3f}, {{glm::vec3(-1.0f, 1.0f, 0.5f), 0.8f, 0}}));
  std::vector<glm::vec3> half(healpix::pixelCount(order), glm::vec3(1.0f));
  Environment probe = constantEnvironment(order, glm::vec3(1.0f));
  for (uint64_t p = 0; p < half.size(); ++p)
    if (probe.direction(order, p, 0.5f, 0.5f).x < 0.0f) half[p] = glm::vec3(0.0f);
  setups.push_back(makeSetup("black-hemisphere", environmentFromPixels(order, half), ggx(0.3f, glm::vec3(0.5f), glm::vec3(0.4f)),
                             {0.3f, 0.8f, 0.0f}));
  const Method methods[] = {Method::Ht, Method::HtVis};
  const int tests = int(setups.size()) * 4 * 3;
  const double zCrit = normalQuantileTwoSided(sidakAlpha(0.01, tests));
  for (const ShadingSetup& s : setups) {
    glm::dvec3 ref = bruteForceIntegral(s, 16);
    glm::dvec3 refError = glm::abs(ref - bruteForceIntegral(s, 8));
    for (Method m : methods)
      for (auto bounds : {MethodOptions::BrdfBounds::Analytic, MethodOptions::BrdfBounds::Table}) {
        MethodOptions options;
        options.brdfBounds = bounds;
        MeanAndError e = repeatedEstimates(s, m, 10000, 16, 4321, options);
        for (int c = 0; c < 3; ++c) {
          double se = std::sqrt(e.stdError[c] * e.stdError[c] + refError[c] * refError[c]);
          EXPECT_LT(std::abs(e.mean[c] - ref[c]) / se, zCrit)
              << s.name << " / " << methodName(m) << (bounds == MethodOptions::BrdfBounds::Table ? " table" : "")
              << " channel " << c << ": mean " << e.mean[c] << " reference " << ref[c] << " std error "
              << e.stdError[c];
        }
      }
  }
}

// The biased variants: their error is bounded by the smoothness threshold,
// and falls with the sample count towards the unbiased result, because more
// samples push acceptance below the smooth nodes, where contributions are
// exact.
TEST(HtSlow, BiasedConvergesToUnbiased) {
  const int order = 5;
  std::vector<ShadingSetup> setups;
  setups.push_back(makeSetup("diffuse-sunrise", sunriseAt(order), lambert(0.8f), {0.3f, 1.0f, 0.2f}));
  setups.push_back(makeSetup("phong-sunrise", sunriseAt(order), phong(20.0f, glm::vec3(0.4f), glm::vec3(0.3f)),
                             {-0.4f, 0.6f, 0.3f}));
  setups.push_back(makeSetup("glossy-sun", smallSky(order), ggx(0.2f, glm::vec3(0.9f)), mirrorOf(kSunDir)));
  const int ns[] = {4, 16, 64, 256};
  for (const ShadingSetup& s : setups) {
    const double ref = bruteForceIntegral(s, 16).g;
    for (Method m : {Method::HtBiased, Method::HtVisBiased})
    for (MethodOptions::BrdfBounds bounds : {MethodOptions::BrdfBounds::Analytic, MethodOptions::BrdfBounds::Table}) {
      const bool table = bounds == MethodOptions::BrdfBounds::Table;
      MethodOptions mo;
      mo.brdfBounds = bounds;
      double previousMse = INFINITY, previousAveraged = 1.0;
      for (int n : ns) {
        const int batches = 400000 / n;
        MeanAndError e = repeatedEstimates(s, m, batches, n, 777, mo);
        double bias = e.mean.g - ref;
        double variance = e.stdError.g * e.stdError.g * batches;
        double mse = bias * bias + variance;
        // The share of samples that use an averaged BRDF value falls.
        HtOptions opt;
        opt.biased = true;
        opt.visibility = m == Method::HtVisBiased;
        opt.brdfTable = table;
        ShadingPoint sp = s.sp;
        sp.material = &s.scene.materials[0];
        const MethodTables tables = htTables(s.scene, opt);
        HtPoint ht(s.scene, sp, opt, tables);
        ht.setBudget(n);
        uint64_t averaged = 0, total = 0;
        std::vector<HtSample> samples;
        for (int run = 0; run < 2000; ++run) {
          traverseRun(ht, uint32_t(run), 3, samples);
          for (const HtSample& x : samples) averaged += x.averaged;
          total += samples.size();
        }
        double share = double(averaged) / double(total);
        // With more samples the traversal goes deeper: the share does not grow.
        EXPECT_LE(share, previousAveraged + 0.02) << s.name << " n " << n;
        // The biased methods stop early somewhere, with either bound kind.
        EXPECT_GT(share, 0.01) << s.name << " " << methodName(m) << (table ? " table" : " analytic") << " n " << n;
        previousAveraged = share;
        std::printf("[ biased   ] %-15s %-13s %-8s n %3d: bias %+.4f (%.1f se), relMSE %.2e, averaged %.3f\n",
                    s.name.c_str(), methodName(m), table ? "table" : "analytic", n, bias / ref,
                    bias / e.stdError.g, mse / (ref * ref), share);
        // The BRDF's value at a smooth node's centre is within 25 % of every
        // value over the node, and errors of both signs average out: the
        // bias stays far below that (at most 0.7 % measured).
        EXPECT_LT(std::abs(bias), 0.02 * ref + 4.0 * e.stdError.g) << s.name << " n " << n;
        EXPECT_LT(mse, previousMse) << s.name << " " << methodName(m) << ": error did not fall at n = " << n;
        previousMse = mse;
        if (n == ns[3]) {
          EXPECT_LT(std::abs(bias), 0.01 * ref + 4.0 * e.stdError.g) << s.name << " " << methodName(m);
        }
      }
    }
  }
}
