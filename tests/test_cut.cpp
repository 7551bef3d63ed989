// ht-cut: the cut of the environment's tree, its density against its own
// samples, the weights' first moments, the fixed sample count, unbiasedness
// against the brute force at low and high counts, and images that the
// thread count never changes.
#include <cmath>
#include <numeric>

#include <gtest/gtest.h>

#include <tbb/global_control.h>

#include "chi2.h"
#include "estimator_harness.h"
#include "ht_cut.h"
#include "render.h"
#include "tables.h"

using namespace ht;
using namespace ht::test;

namespace {

constexpr int kEnvOrder = 5;

const Environment& sunrise() { return sunriseCached(kEnvOrder); }

std::vector<ShadingSetup> setups() { return productSetups(kEnvOrder); }

// One point's density over the cut.
struct PreparedPoint {
  ShadingPoint sp;
  MethodTables tables;
  EstimateCounters counters;
  std::unique_ptr<Shading> shading;
  std::unique_ptr<CutPoint> point;
  CutDensity density;
};

void prepare(const ShadingSetup& s, PreparedPoint& p) {
  p.sp = s.sp;
  p.sp.material = &s.scene.materials[0];
  p.tables = prepareTables(s.scene, Method::HtCut);
  p.shading = std::make_unique<Shading>(s.scene, p.sp, p.counters);
  const CutOptions options;
  p.point = std::make_unique<CutPoint>(s.scene, p.sp, *p.shading, options, p.tables.own<EnvCut>(), p.tables.geometry());
  p.density.reset(*p.point, s.scene.environment, options);
}

void expectUnbiased(const std::vector<int>& counts, int batches, uint32_t seedBase, int sub) {
  expectUnbiasedAgainstBruteForce(setups(), Method::HtCut, counts, batches, seedBase, sub);
}

}  // namespace

// The cut partitions the sphere: its nodes, along the nested index, hold
// every pixel of the map once, and the lookup names the node holding each;
// it has the nodes asked for, the sun's in nodes of their own; a node's
// first moment is its children's sum and has the length of its power
// where its light comes from one pixel.
TEST(Cut, NodesPartitionTheSphere) {
  const Environment env = onePixelSun(7);
  const std::shared_ptr<const HtGeometry> g = buildHtGeometry(env.order);
  for (int k : {12, 64, 256, HT_CUT_MAX_NODES}) {
    const EnvCut cut = buildEnvCut(env, *g, k);
    EXPECT_LE(cut.nodes.size(), size_t(k));
    EXPECT_GT(cut.nodes.size(), size_t(k) - 4);
    std::vector<int> holder(healpix::pixelCount(env.order), -1);
    uint64_t next = 0;
    for (size_t i = 0; i < cut.nodes.size(); ++i) {
      const CutNode& n = cut.nodes[i];
      const uint64_t leaves = uint64_t(1) << (2 * (env.order - n.level));
      ASSERT_EQ(n.node * leaves, next) << "node " << i << " is not next along the nested index";
      for (uint64_t l = next; l < next + leaves; ++l) holder[l] = int(i);
      next += leaves;
      ASSERT_LE(n.level, kCutMaxLevel);
    }
    ASSERT_EQ(next, healpix::pixelCount(env.order));
    for (uint64_t l = 0; l < holder.size(); ++l) ASSERT_EQ(int(cut.cutNodeOf(env, l)), holder[l]) << "pixel " << l;
    // Past the base faces, the sun's pixel sits in a node of the deepest
    // level the cut allows: power is what splits.
    if (k > 12) {
      EXPECT_EQ(cut.nodes[cut.cutNodeOf(env, env.pixelOf(kSunDir))].level, kCutMaxLevel) << k << " nodes";
    }
  }
  const EnvCut cut = buildEnvCut(env, *g, 64);
  for (int level = 0; level < cut.momentLevel; ++level)
    for (uint64_t i = 0; i < MaxAvgTree::levelSize(level); ++i) {
      const uint64_t c = MaxAvgTree::levelOffset(level + 1) + 4 * i;
      const glm::vec3 sum = cut.moment[c] + cut.moment[c + 1] + cut.moment[c + 2] + cut.moment[c + 3];
      ASSERT_LT(glm::length(cut.moment[MaxAvgTree::levelOffset(level) + i] - sum), 1e-5f * glm::length(sum) + 1e-9f);
    }
  const uint64_t sunAt = MaxAvgTree::levelOffset(cut.momentLevel) + (env.pixelOf(kSunDir) >> 2 * (7 - cut.momentLevel));
  const float power = env.tree.avgv[sunAt] * float(healpix::pixelSolidAngle(cut.momentLevel));
  EXPECT_NEAR(glm::length(cut.moment[sunAt]), power, 1e-3f * power);
}

// A render's K: 8 x spp within [192, HT_CUT_MAX_NODES] unless given; the
// CPU reference and the GPU path both take it from optionsForSpp.
TEST(Cut, SizeFollowsSppUnlessGiven) {
  EXPECT_EQ(optionsForSpp(MethodOptions{}, 1).cutNodes, 192);
  EXPECT_EQ(optionsForSpp(MethodOptions{}, 16).cutNodes, 192);
  EXPECT_EQ(optionsForSpp(MethodOptions{}, 32).cutNodes, 256);
  EXPECT_EQ(optionsForSpp(MethodOptions{}, 48).cutNodes, 384);
  EXPECT_EQ(optionsForSpp(MethodOptions{}, 64).cutNodes, 512);
  EXPECT_EQ(optionsForSpp(MethodOptions{}, 1 << 20).cutNodes, HT_CUT_MAX_NODES);
  MethodOptions given;
  given.cutNodes = 100;
  EXPECT_EQ(optionsForSpp(given, 1024).cutNodes, 100);
  Scene scene = readSceneFile(std::string(HT_TEST_DATA) + "/scenes/spheres.json");
  scene.environment = sunriseAt(6);
  const MethodTables tables = prepareTables(scene, Method::HtCut, optionsForSpp(MethodOptions{}, 64));
  EXPECT_EQ(tables.own<EnvCut>().nodes.size(), 510u);  // 12 + 3 x 166: each split adds three
}

// A disc's share beyond a straight edge is the circular segment's area
// over the disc's, to within 0.0016, and right in order where the disc
// barely reaches past the edge (within 0.5 % of it from x = 0.001), where a
// partly covered node's visible light is otherwise underweighted.
TEST(Cut, SegmentShareFollowsTheCircularSegment) {
  const auto exact = [](double x) {
    const double t = 2.0 * std::acos(1.0 - 2.0 * x);
    return (t - std::sin(t)) / (2.0 * M_PI);
  };
  EXPECT_EQ(cutSegmentShare(0.0f), 0.0f);
  EXPECT_EQ(cutSegmentShare(1.0f), 1.0f);
  float last = 0.0f;
  for (int i = 0; i <= 1000; ++i) {
    const float x = float(i) / 1000.0f;
    const float share = cutSegmentShare(x);
    EXPECT_NEAR(share, exact(double(x)), 0.0016) << x;
    EXPECT_GE(share, last) << x;
    last = share;
  }
  for (const double x : {0.001, 0.003, 0.01, 0.03}) {
    EXPECT_NEAR(cutSegmentShare(float(x)) / exact(x), 1.0, 0.005) << x;
    EXPECT_NEAR((1.0 - cutSegmentShare(float(1.0 - x))) / exact(x), 1.0, 0.005) << x;
  }
}

// A node that caps cover in part keeps about the share of its area they
// leave open: at a point under two spheres, over the nodes of levels 2 to 4
// above its horizon that a cap covers in part, the open share visibleShare
// gives (at least the weights' 0.03) and the share of 8 x 8 points per
// pixel that no sphere blocks differ by less than 0.05 on average, and
// where 2 % to 30 % of a node is open the geometric mean of given over
// open is above 0.9 (1.01; a smoothstep in place of the circular segment
// gives 0.77).
TEST(Cut, CoveredShareFollowsTheOpenArea) {
  const ShadingSetup s = setups()[0];
  ASSERT_EQ(s.name, "flat-diffuse-sunrise-occluded");
  PreparedPoint p;
  prepare(s, p);
  const Environment& env = s.scene.environment;
  const HtGeometry& g = p.tables.geometry();
  const CutPoint& point = *p.point;
  ASSERT_EQ(point.caps.count, 2);
  const float minPartial = CutOptions{}.minPartialVisibility;
  int partial = 0, nearlyCovered = 0;
  double difference = 0.0, logRatio = 0.0;
  for (int level = 2; level <= 4; ++level) {
    for (uint64_t node = 0; node < healpix::pixelCount(level); ++node) {
      const glm::vec3& centre = g.centers[MaxAvgTree::levelOffset(level) + node];
      if (!(glm::dot(centre, point.normal) > g.levelSinRadius[size_t(level)])) continue;
      bool inside = false, cut = false;
      for (size_t j = 0; j < size_t(point.caps.count); ++j) {
        const float d = glm::dot(centre, glm::vec3(point.caps.x[j], point.caps.y[j], point.caps.z[j]));
        inside |= d >= point.caps.inside[size_t(level) * kCutMaxCaps + j];
        cut |= d > point.caps.outside[size_t(level) * kCutMaxCaps + j];
      }
      if (inside || !cut) continue;
      const int shift = 2 * (env.order - level);
      int points = 0, visible = 0;
      for (uint64_t leaf = node << shift; leaf < (node + 1) << shift; ++leaf)
        for (int i = 0; i < 8; ++i)
          for (int j = 0; j < 8; ++j) {
            const glm::vec3 wi = env.direction(env.order, leaf, (float(i) + 0.5f) / 8.0f, (float(j) + 0.5f) / 8.0f);
            ++points;
            visible += !occluded(s.scene, p.shading->origin, wi);
          }
      const double open = double(visible) / points;
      const double given = std::max(point.visibleShare(centre, level), minPartial);
      ++partial;
      difference += std::abs(given - open);
      if (open >= 0.02 && open <= 0.3) {
        ++nearlyCovered;
        logRatio += std::log(given / open);
      }
    }
  }
  ASSERT_GE(partial, 100);
  ASSERT_GE(nearlyCovered, 20);
  EXPECT_LT(difference / partial, 0.05);
  EXPECT_GT(std::exp(logRatio / nearlyCovered), 0.9);
}

// Directions drawn from uniform points of the cut's prefix sums follow the
// density the point reports (chi-square over HEALPix bins, Sidak-corrected
// over the setups); each sample's pdf is the one pdf(pixel) gives.
TEST(Cut, DensityMatchesItsSamples) {
  const std::vector<ShadingSetup> all = setups();
  constexpr int kBinOrder = 3;
  constexpr int kSamples = 200000;
  for (const ShadingSetup& s : all) {
    PreparedPoint p;
    prepare(s, p);
    ASSERT_GT(p.density.total(), 0.0f) << s.name;
    const Environment& env = s.scene.environment;
    std::vector<double> expected(healpix::pixelCount(kBinOrder), 0.0);
    for (uint64_t leaf = 0; leaf < healpix::pixelCount(env.order); ++leaf)
      expected[leaf >> (2 * (env.order - kBinOrder))] += double(p.density.pdf(leaf)) * env.pixelSolidAngle() * kSamples;
    double worstPdf = 0.0;
    int wrongLeaf = 0;
    auto sample = [&](Rng& rng) {
      const double x = rng.next();
      const glm::vec2 u = rng.next2();
      const EnvSample es = p.density.sample(p.density.node(x), glm::dvec2(u));
      if (env.pixelOf(es.dir) != es.pixel) ++wrongLeaf;
      worstPdf = std::max(worstPdf, std::abs(double(es.pdf) / double(p.density.pdf(es.pixel)) - 1.0));
      return glm::dvec3(env.toHealpixFrame(es.dir));
    };
    expectDensitiesMatch({{s.name, sample, nullptr, kBinOrder, 0, kSamples, std::move(expected)}}, 7, 3,
                         int(all.size()));
    EXPECT_LE(wrongLeaf, kSamples / 10000) << s.name;  // a direction a rounding across a pixel's border
    EXPECT_LT(worstPdf, 1e-5) << s.name;
  }
}

// The control variate on colour follows a direction down to its pixel:
// the drift a sample reports (each descent step's expected chroma less the
// drawn child's, the last node's less the pixel's) has mean 0 in every
// channel (z-tests, Sidak-corrected over setups and channels), and the
// chroma it leaves to the estimate, the pixel's less the node's plus the
// drift, varies far less than the pixel's less the node's.
TEST(Cut, ColourDriftHasMeanZero) {
  constexpr int kSamples = 20000;
  const std::vector<ShadingSetup> all = setups();
  std::vector<PreparedPoint> points(all.size());
  int diffuse = 0;
  for (size_t i = 0; i < all.size(); ++i) {
    prepare(all[i], points[i]);
    diffuse += !points[i].point->lobeOnly && points[i].point->diffuse > 0.0f;
  }
  ASSERT_GE(diffuse, 3);
  const double zCrit = normalQuantileTwoSided(1.0 - std::pow(1.0 - 0.01, 1.0 / (3.0 * diffuse)));
  double before = 0.0, after = 0.0;
  for (size_t i = 0; i < all.size(); ++i) {
    const PreparedPoint& p = points[i];
    if (p.point->lobeOnly || !(p.point->diffuse > 0.0f)) continue;
    const Environment& env = all[i].scene.environment;
    Rng rng(11, uint32_t(i));
    glm::dvec3 sum(0.0), squares(0.0);
    for (int n = 0; n < kSamples; ++n) {
      const uint32_t k = p.density.node(rng.next());
      glm::dvec3 drift;
      const EnvSample es = p.density.sample(k, glm::dvec2(rng.next2()), &drift);
      ASSERT_GT(es.pdf, 0.0f);
      sum += drift;
      squares += drift * drift;
      const glm::vec3 r = env.radiance[es.pixel];
      const glm::dvec3 pixel = glm::dvec3(r / luminance(r)), node = glm::dvec3(p.point->cut.nodes[k].chroma);
      const glm::dvec3 left = pixel - node + drift, whole = pixel - node;
      before += glm::dot(whole, whole);
      after += glm::dot(left, left);
    }
    const glm::dvec3 mean = sum / double(kSamples);
    for (int c = 0; c < 3; ++c) {
      const double sd = std::sqrt(std::max(squares[c] / kSamples - mean[c] * mean[c], 0.0) / kSamples);
      EXPECT_LE(std::abs(mean[c]), zCrit * sd + 1e-12) << all[i].name << " channel " << c;
    }
  }
  EXPECT_LT(after, 0.5 * before);
  std::printf("[ drift    ] chroma left to the estimate: %.3e of the node's %.3e\n", after, before);
}

// A point with a diffuse lobe weighs the cut by columns, a level at a
// time, and its refined nodes' children by columns of their own: every
// node's weight, and so its probability, is bit for bit the one CutPoint::
// weight gives node by node, children where the horizon or a cap cuts it.
TEST(Cut, ColumnsWeighAsNodeByNode) {
  int refined = 0, partial = 0, withCaps = 0;
  for (const ShadingSetup& s : setups()) {
    PreparedPoint p;
    prepare(s, p);
    const CutPoint& point = *p.point;
    if (point.lobeOnly || !(point.diffuse > 0.0f)) continue;
    withCaps += point.caps.count > 0;
    const EnvCut& cut = point.cut;
    const size_t K = cut.nodes.size();
    std::vector<float> cum(K + 1, 0.0f);
    for (size_t k = 0; k < K; ++k) {
      bool uncertain = false;
      float w = point.weight(cut.lights[k], false, &uncertain);
      if (w > 0.0f && point.caps.count > 0) {
        CutPoint open = point;
        open.caps.count = 0;
        partial += open.weight(cut.lights[k], false) != w;
      }
      if (uncertain && cut.nodes[k].level < cut.momentLevel) {
        ++refined;
        float children = 0.0f;
        for (size_t j = 0; j < 4; ++j) children += point.weight(cut.lights[K + 4 * k + j], false);
        if (children > 0.0f) w = children;
      }
      cum[k + 1] = cum[k] + w;
    }
    ASSERT_EQ(p.density.total(), cum[K]) << s.name;
    for (size_t k = 0; k < K; ++k)
      ASSERT_EQ(p.density.nodeProbability(uint32_t(k)), double((cum[k + 1] - cum[k]) / cum[K])) << s.name << " node " << k;
  }
  // The setups reach the columns' every branch: caps, nodes they cover in
  // part, nodes refined.
  EXPECT_GT(withCaps, 0);
  EXPECT_GT(partial, 0);
  EXPECT_GT(refined, 0);
}

// The density is positive wherever a diffuse point's integrand can be,
// which lets it draw no BRDF directions: every pixel above the horizon
// that the caps leave visible has p_c > 0.
TEST(Cut, DiffuseDensityCoversTheVisibleHemisphere) {
  std::vector<ShadingSetup> points;
  for (ShadingSetup& s : setups())
    if (s.scene.materials[0].type == MaterialType::Lambert) points.push_back(std::move(s));
  // Normals off the map's pole, whose horizons cross the nodes obliquely.
  for (const glm::vec3 n : {glm::vec3(0.3f, 1.0f, 0.1f), glm::vec3(-0.7f, 0.4f, 0.5f), glm::vec3(0.2f, -0.3f, 1.0f)}) {
    ShadingSetup s = makeSetup("tilted-diffuse-sunrise", sunrise(), lambert(0.8f), n);
    s.scene.planes.clear();
    s.sp.normal = glm::normalize(n);
    points.push_back(std::move(s));
  }
  for (const ShadingSetup& s : points) {
    PreparedPoint p;
    prepare(s, p);
    const Environment& env = s.scene.environment;
    int uncovered = 0;
    for (uint64_t leaf = 0; leaf < healpix::pixelCount(env.order); ++leaf) {
      for (float dx : {0.1f, 0.5f, 0.9f}) {
        const glm::vec3 wi = env.direction(env.order, leaf, dx, 0.5f);
        if (env.pixelOf(wi) != leaf || env.radiance[leaf] == glm::vec3(0.0f)) continue;
        if (visibleReflectance(s.scene, p.sp, wi) == glm::vec3(0.0f)) continue;
        uncovered += !(p.density.pdf(leaf) > 0.0f);
      }
    }
    EXPECT_EQ(uncovered, 0) << s.name;
  }
}

// The mean of many estimates matches the brute-force integral at 1, 5 and
// 16 directions: the one-direction mixture, the fixed counts, the colour
// control variate.
TEST(Cut, UnbiasedAgainstBruteForce) { expectUnbiased({1, 5, 16}, 4000, 500, 8); }

// The weights are a function of the point and the map alone: the image is
// the same whatever the thread count, and every shaded pixel draws spp
// directions.
TEST(Cut, ThreadsNeverChangeTheImage) {
  Scene scene = readSceneFile(std::string(HT_TEST_DATA) + "/scenes/spheres.json");
  scene.environment = sunriseAt(6);
  RenderSettings rs;
  rs.method = Method::HtCut;
  rs.spp = 4;
  rs.width = 48;
  rs.height = 24;
  const RenderResult first = renderCpu(scene, rs);
  RenderResult oneThread;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    oneThread = renderCpu(scene, rs);
  }
  EXPECT_EQ(first.image.pixels, oneThread.image.pixels);
  EXPECT_EQ(first.counters.directions, uint64_t(rs.spp) * first.shadedPixels);
  EXPECT_LE(first.counters.shadowRays, first.counters.directions);
}

// Where users go: 256 and 1024 directions per estimate on every setup
// (z-test against the brute force, Sidak-corrected), with exact counts.
TEST(CutSlow, UnbiasedAtHighSpp) {
  expectUnbiased({256, 1024}, 300, 900, 12);
  for (const ShadingSetup& s : setups()) {
    ShadingPoint sp = s.sp;
    sp.material = &s.scene.materials[0];
    const MethodTables tables = prepareTables(s.scene, Method::HtCut);
    for (int n : {256, 1024}) {
      Rng rng(3, 1);
      EstimateCounters counters;
      estimateDirect(s.scene, sp, Method::HtCut, n, rng, counters, tables);
      EXPECT_EQ(counters.directions, uint64_t(n)) << s.name;
      EXPECT_LE(counters.shadowRays, uint64_t(n)) << s.name;
    }
  }
}
