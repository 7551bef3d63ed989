// The sphere BVH only prunes: closest hits and shadow rays through it equal
// the linear scan's, hit for hit, on random sphere sets with the cases that
// break careless traversals (touching, nested, identical, huge and tiny
// spheres, rays from inside, rays along the axes).
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "bvh.h"
#include "scene.h"

using namespace ht;

namespace {

Scene withSpheres(std::vector<Sphere> spheres) {
  Scene s;
  s.spheres = std::move(spheres);
  s.sphereBvh = buildBvh(s.spheres);
  return s;
}

// The same scene without its BVH: rays scan every sphere.
Scene linear(const Scene& s) {
  Scene l = s;
  l.sphereBvh = Bvh{};
  return l;
}

std::vector<Sphere> randomSpheres(std::mt19937& rng, int n) {
  std::uniform_real_distribution<float> u(-10.0f, 10.0f), r(0.0f, 1.0f);
  std::vector<Sphere> s;
  for (int i = 0; i < n; ++i) {
    const float kind = r(rng);
    const float radius = kind < 0.1f ? 1e-4f : kind < 0.15f ? 50.0f : 0.05f + 1.5f * r(rng);
    s.push_back({glm::vec3(u(rng), u(rng), u(rng)), radius, i % 7});
    if (i % 11 == 3) s.push_back({s.back().center, s.back().radius * 0.5f, 100 + i});  // nested
    if (i % 13 == 5) s.push_back({s.back().center, s.back().radius, 300 + i});            // identical: ties
    if (i % 17 == 7) {                                                                   // touching
      const Sphere& a = s.back();
      s.push_back({a.center + glm::vec3(2.0f * a.radius, 0.0f, 0.0f), a.radius, 200 + i});
    }
  }
  return s;
}

void expectSameHits(const Scene& bvhScene, std::mt19937& rng, int rays) {
  const Scene scan = linear(bvhScene);
  std::uniform_real_distribution<float> u(-12.0f, 12.0f);
  std::normal_distribution<float> g;
  int hits = 0;
  for (int k = 0; k < rays; ++k) {
    Ray ray;
    // Some rays start inside a sphere, some run along an axis.
    ray.origin = k % 5 == 0 ? bvhScene.spheres[size_t(k) % bvhScene.spheres.size()].center
                            : glm::vec3(u(rng), u(rng), u(rng));
    ray.dir = k % 7 == 0 ? glm::vec3(0.0f, 0.0f, k % 2 ? 1.0f : -1.0f) : glm::normalize(glm::vec3(g(rng), g(rng), g(rng)));
    Hit a, b;
    const bool ha = intersectScene(bvhScene, ray, 1e-4f, INFINITY, a);
    const bool hb = intersectScene(scan, ray, 1e-4f, INFINITY, b);
    ASSERT_EQ(ha, hb) << "ray " << k;
    if (ha) {
      ++hits;
      ASSERT_EQ(a.t, b.t) << "ray " << k;
      ASSERT_EQ(a.material, b.material) << "ray " << k;
      ASSERT_EQ(a.normal, b.normal) << "ray " << k;
      ASSERT_EQ(a.position, b.position) << "ray " << k;
    }
    ASSERT_EQ(occluded(bvhScene, ray.origin, ray.dir), occluded(scan, ray.origin, ray.dir)) << "ray " << k;
  }
  EXPECT_GT(hits, rays / 10);  // the rays do hit things
}

}  // namespace

TEST(Bvh, EverySphereOnceInBoxesThatHoldIt) {
  std::mt19937 rng(1);
  const std::vector<Sphere> spheres = randomSpheres(rng, 3000);
  const Bvh bvh = buildBvh(spheres);
  ASSERT_EQ(bvh.spheres, spheres.size());
  std::vector<int> seen(spheres.size(), 0);
  std::vector<int> depth(bvh.nodes.size(), 0);
  int maxDepth = 0;
  for (size_t i = 0; i < bvh.nodes.size(); ++i) {
    const BvhNode& n = bvh.nodes[i];
    maxDepth = std::max(maxDepth, depth[i]);
    if (n.count == 0) {
      ASSERT_LT(n.first, bvh.nodes.size());
      ASSERT_GT(n.first, i + 1);
      depth[i + 1] = depth[n.first] = depth[i] + 1;
      for (size_t c : {i + 1, size_t(n.first)})
        for (int a = 0; a < 3; ++a) {
          EXPECT_LE(n.lo[a], bvh.nodes[c].lo[a]);
          EXPECT_GE(n.hi[a], bvh.nodes[c].hi[a]);
        }
      continue;
    }
    ASSERT_LE(n.count, kBvhLeafSize);
    for (uint32_t k = n.first; k < n.first + n.count; ++k) {
      const Sphere& s = spheres[bvh.order[k]];
      ++seen[bvh.order[k]];
      for (int a = 0; a < 3; ++a) {
        EXPECT_LE(n.lo[a], s.center[a] - s.radius);
        EXPECT_GE(n.hi[a], s.center[a] + s.radius);
      }
    }
  }
  for (int c : seen) ASSERT_EQ(c, 1);
  EXPECT_LT(maxDepth, kBvhMaxDepth);  // the traversal's stack
}

TEST(Bvh, HitsEqualTheLinearScan) {
  for (int n : {1, 3, 5, 16, 200, 2000}) {
    std::mt19937 rng{uint32_t(n)};
    const Scene s = withSpheres(randomSpheres(rng, n));
    SCOPED_TRACE(n);
    expectSameHits(s, rng, 20000);
  }
}

TEST(Bvh, DegenerateSetsEqualTheLinearScan) {
  std::mt19937 rng(9);
  // Every centre in one point; all on a line; a grid of touching spheres.
  std::vector<Sphere> same, line, grid;
  for (int i = 0; i < 100; ++i) same.push_back({glm::vec3(1.0f, 2.0f, 3.0f), 0.5f + 0.01f * float(i % 10), i});
  for (int i = 0; i < 100; ++i) line.push_back({glm::vec3(0.1f * float(i), 0.0f, 0.0f), 0.05f, i});
  for (int x = 0; x < 12; ++x)
    for (int z = 0; z < 12; ++z) grid.push_back({glm::vec3(2.0f * float(x), 0.0f, 2.0f * float(z)), 1.0f, x + z});
  for (auto* set : {&same, &line, &grid}) expectSameHits(withSpheres(*set), rng, 20000);
}

namespace {
// The slab test as std::fmin / std::fmax give it, NaN of 0 x inf included.
bool slabReference(const BvhNode& node, const glm::vec3& o, const glm::vec3& inv, float tMax, float& t0) {
  float enter = 0.0f, exit = tMax;
  for (int a = 0; a < 3; ++a) {
    const float ta = (node.lo[a] - o[a]) * inv[a], tb = (node.hi[a] - o[a]) * inv[a];
    enter = std::fmax(enter, std::fmin(ta, tb));
    exit = std::fmin(exit, std::fmax(ta, tb));
  }
  t0 = enter;
  return enter <= exit + 1e-5f * (std::fabs(enter) + std::fabs(exit));
}
}  // namespace

// rayBox's inline minimum and maximum answer as fmin and fmax do, on rays
// along the axes that start on a box's planes (0 x inf) and on any others.
TEST(Bvh, SlabTestEqualsFminFmax) {
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> pick(-2, 2);
  std::normal_distribution<float> g;
  const BvhNode box{glm::vec3(-1.0f, -1.0f, -1.0f), glm::vec3(1.0f, 1.0f, 1.0f), 0, 1};
  int entered = 0, nans = 0;
  for (int k = 0; k < 20000; ++k) {
    // Coordinates on the box's planes, its middle and outside it.
    glm::vec3 o(float(pick(rng)), float(pick(rng)), float(pick(rng)));
    glm::vec3 d = k % 2 ? glm::vec3(float(pick(rng)), float(pick(rng)), float(pick(rng))) : glm::vec3(g(rng), g(rng), g(rng));
    if (d == glm::vec3(0.0f)) d.z = 1.0f;
    const glm::vec3 inv = 1.0f / d;
    for (int a = 0; a < 3; ++a) nans += std::isnan((box.lo[a] - o[a]) * inv[a]) ? 1 : 0;
    for (const float tMax : {INFINITY, 10.0f, 0.5f}) {
      float t0 = 0.0f, r0 = 0.0f;
      const bool hit = rayBox(box, o, inv, tMax, t0), ref = slabReference(box, o, inv, tMax, r0);
      ASSERT_EQ(hit, ref) << "ray " << k << " tMax " << tMax;
      ASSERT_EQ(t0, r0) << "ray " << k << " tMax " << tMax;
      entered += hit ? 1 : 0;
    }
  }
  EXPECT_GT(nans, 1000);  // the 0 x inf case is exercised
  EXPECT_GT(entered, 1000);
}

// Centres too far apart or too close together for a float bin scale: the
// build splits at the median instead (and writes nothing out of bounds).
TEST(Bvh, ExtremeCentresBuild) {
  std::vector<Sphere> far, near;
  for (int i = 0; i < 9; ++i) far.push_back({glm::vec3(i == 0 ? -3e38f : i == 1 ? 3e38f : float(i), 0.0f, 0.0f), 1.0f, i});
  for (int i = 0; i < 9; ++i) near.push_back({glm::vec3(i % 2 ? 1e-39f : 0.0f, 0.0f, 0.0f), 0.5f, i});
  for (auto* set : {&far, &near}) {
    const Bvh bvh = buildBvh(*set);
    std::vector<int> seen(set->size(), 0);
    for (uint32_t i : bvh.order) ++seen[i];
    for (int c : seen) EXPECT_EQ(c, 1);
  }
  std::mt19937 rng(3);
  expectSameHits(withSpheres(near), rng, 2000);
}

// A scene from a file gets its BVH; scenes whose spheres changed count
// after it fall back to the scan.
TEST(Bvh, ParsedScenesHaveOne) {
  const Scene s = parseScene(R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
    "environment": {"file": "x.exr"}, "materials": {"m": {"type": "lambert", "albedo": 0.5}},
    "spheres": [{"center": [0, 0, 0], "radius": 1, "material": "m"}, {"center": [3, 0, 0], "radius": 1, "material": "m"}]})",
                             "inline.json");
  EXPECT_EQ(s.sphereBvh.spheres, 2u);
  EXPECT_FALSE(s.sphereBvh.nodes.empty());
}

// capSpheres picks what a brute-force ranking of every sphere picks (the k
// largest sines above the plane, ties to the lower index), through the BVH
// and without it, from points outside, on and inside spheres.
TEST(Bvh, CapSpheresAreTheBruteForceRanking) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-12.0f, 12.0f);
  std::normal_distribution<float> g;
  for (int n : {0, 1, 15, 16, 17, 60, 1000}) {
    const Scene scene = withSpheres(n > 0 ? randomSpheres(rng, n) : std::vector<Sphere>{});
    const Scene scan = linear(scene);
    const size_t count = scene.spheres.size();
    int trimmed = 0;
    for (int p = 0; p < 200; ++p) {
      const glm::vec3 origin = p % 4 == 0 && count > 0 ? scene.spheres[size_t(p) % count].center + glm::vec3(0.01f)
                                                       : glm::vec3(u(rng), u(rng), u(rng));
      const glm::vec3 normal = glm::normalize(glm::vec3(g(rng), g(rng), g(rng)));
      for (size_t k : {size_t(0), size_t(1), size_t(5), size_t(7), size_t(15)}) {
        std::vector<uint32_t> expected;
        if (count <= k) {
          for (uint32_t i = 0; i < count; ++i) expected.push_back(i);
        } else {
          std::vector<std::pair<float, uint32_t>> ranked;
          for (uint32_t i = 0; i < count; ++i) {
            float sine;
            if (capRank(scene.spheres[i], origin, normal, sine)) ranked.push_back({-sine, i});
          }
          std::sort(ranked.begin(), ranked.end());
          for (size_t j = 0; j < std::min(k, ranked.size()); ++j) expected.push_back(ranked[j].second);
          std::sort(expected.begin(), expected.end());
          trimmed += k == 15 && ranked.size() > k;
        }
        ASSERT_EQ(capSpheres(scene, origin, normal, k), expected) << n << " spheres, point " << p << ", k " << k;
        ASSERT_EQ(capSpheres(scan, origin, normal, k), expected) << n << " spheres, point " << p << ", k " << k;
      }
    }
    if (n >= 60) {
      EXPECT_GT(trimmed, 100) << n;  // at k = 15 the ranking decides, not the count
    }
  }
}

// A sphere wholly below the plane through the point is not ranked; one
// that reaches above it, or holds the point, is.
TEST(Bvh, CapRankLeavesOutSpheresBelowTheHorizon) {
  const glm::vec3 origin(0.0f), up(0.0f, 1.0f, 0.0f);
  float sine = -1.0f;
  EXPECT_FALSE(capRank({glm::vec3(0.0f, -2.0f, 0.0f), 1.0f, 0}, origin, up, sine));
  EXPECT_TRUE(capRank({glm::vec3(0.0f, -0.5f, 0.0f), 1.0f, 0}, origin, up, sine));
  EXPECT_FLOAT_EQ(sine, 1.0f);  // holds the point
  EXPECT_TRUE(capRank({glm::vec3(3.0f, -0.5f, 4.0f), 1.0f, 0}, origin, up, sine));
  EXPECT_NEAR(sine, 1.0f / std::sqrt(25.25f), 1e-6f);
  EXPECT_FALSE(capRank({origin, 1.0f, 0}, origin, up, sine));  // centred on the point: no direction
}
