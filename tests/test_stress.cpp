// Stability where methods fail: every method on every scene of
// data/scenes/stress, at a small size and a reduced environment resolution,
// gives finite, non-negative pixels and, at shading points taken from the
// image, estimates that agree with the brute-force integral (z-test).
#include <gtest/gtest.h>

#include <filesystem>

#include "estimator_harness.h"
#include "ht_cut.h"
#include "render.h"

using namespace ht;
using namespace ht::test;

namespace {

std::vector<std::string> stressScenes() {
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(std::string(HT_TEST_DATA) + "/scenes/stress"))
    if (e.path().extension() == ".json") files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  return files;
}

Scene loadSmall(const std::string& path, int nside) {
  Scene s = readSceneFile(path);
  s.environmentDesc.nside = nside;
  loadEnvironment(s);
  return s;
}


}  // namespace

TEST(Stress, ScenesExist) { EXPECT_GE(stressScenes().size(), 8u); }

TEST(Stress, EveryMethodGivesFiniteNonNegativePixels) {
  MethodOptions options;
  options.oracleOrder = 2;
  for (const std::string& path : stressScenes()) {
    Scene scene = loadSmall(path, 16);
    for (const MethodSpec& m : allMethods()) {
      RenderSettings rs;
      rs.method = m.method;
      rs.spp = 4;
      rs.width = 24;
      rs.height = 12;
      rs.options = options;
      RenderResult r = renderCpu(scene, rs);
      int bad = 0;
      for (const glm::vec3& p : r.image.pixels)
        for (int c = 0; c < 3; ++c) bad += !(std::isfinite(p[c]) && p[c] >= 0.0f);
      EXPECT_EQ(bad, 0) << path << " / " << m.name;
    }
  }
}

// `count` shading points of a scene (at Nside `nside`), from pixels that hit
// something, each with the hit's material first (the harness shades
// material 0).
std::vector<ShadingSetup> shadingPoints(const std::string& path, int nside, size_t count = 2) {
  Scene scene = loadSmall(path, nside);
  std::vector<ShadingSetup> points;
  for (float fy : {0.45f, 0.75f, 0.6f, 0.9f}) {
    for (float fx : {0.3f, 0.7f, 0.5f}) {
      if (points.size() == count) break;
      Ray ray = cameraRay(scene.camera, 64, 32, fx * 64, fy * 32);
      Hit hit;
      if (!intersectScene(scene, ray, 0.0f, INFINITY, hit)) continue;
      ShadingSetup s;
      s.name = std::filesystem::path(path).stem().string() + " @" + std::to_string(fx) + "," + std::to_string(fy);
      s.scene = scene;
      s.sp = {hit.position, hit.normal, -ray.dir, nullptr, hit.flat};
      std::swap(s.scene.materials[0], s.scene.materials[hit.material]);
      for (Sphere& sp : s.scene.spheres)
        sp.material = sp.material == 0 ? hit.material : sp.material == hit.material ? 0 : sp.material;
      for (Plane& pl : s.scene.planes)
        pl.material = pl.material == 0 ? hit.material : pl.material == hit.material ? 0 : pl.material;
      points.push_back(std::move(s));
    }
  }
  EXPECT_EQ(points.size(), count) << path;
  return points;
}

// Two shading points per scene, from pixels that hit something.
TEST(StressSlow, EveryUnbiasedMethodAgreesWithBruteForce) {
  struct Point {
    std::string name;
    ShadingSetup setup;
  };
  std::vector<Point> points;
  for (const std::string& path : stressScenes())
    for (ShadingSetup& s : shadingPoints(path, 32)) points.push_back({s.name, std::move(s)});
  std::vector<MethodSpec> methods;
  for (const MethodSpec& m : allMethods())
    if (!m.biased && m.estimate) methods.push_back(m);  // restir: test_restir.cpp
  const int tests = int(points.size() * methods.size());
  const double zCrit = normalQuantileTwoSided(1.0 - std::pow(1.0 - 0.01, 1.0 / tests));
  MethodOptions options;
  options.oracleOrder = 3;
  for (const Point& p : points) {
    const double ref = bruteForceIntegral(p.setup, 12).g;
    const double refError = std::abs(ref - bruteForceIntegral(p.setup, 6).g);
    for (const MethodSpec& m : methods) {
      // One-direction samplers are cheap and heavy-tailed here: many samples.
      const bool cheap = m.method == Method::Uniform || m.method == Method::Cosine || m.method == Method::Env ||
                         m.method == Method::Brdf || m.method == Method::Mis;
      // wis is heavy-tailed where a node's centre misses the BRDF's lobe
      // and its floor density is all that covers it (sphere-field): its
      // standard error settles only with many more samples.
      const int batches = m.method == Method::Oracle ? 1000 : cheap ? 50000 : m.method == Method::Wis ? 40000 : 4000;
      MeanAndError e = repeatedEstimates(p.setup, m.method, batches, 8, 2024, options);
      double se = std::sqrt(e.stdError.g * e.stdError.g + refError * refError);
      if (se == 0.0) {
        EXPECT_NEAR(e.mean.g, ref, 1e-6 * ref + 1e-12) << p.name << " / " << m.name;
        continue;
      }
      EXPECT_LT(std::abs(e.mean.g - ref) / se, zCrit)
          << p.name << " / " << m.name << ": mean " << e.mean.g << " reference " << ref << " std error "
          << e.stdError.g;
    }
  }
}

// On the sphere field (1024 spheres, one plane) a shading point keeps the
// caps of its 15 largest spheres and the plane's, ht-cut those of its 7
// largest and the plane's unless the point lies on it, and the methods
// whose density has caps stay unbiased: a sphere left out only leaves
// density where its shadow rays return 0.
TEST(Stress, SphereFieldKeepsTheLargestCapsUnbiased) {
  const std::vector<ShadingSetup> points =
      shadingPoints(std::string(HT_TEST_DATA) + "/scenes/stress/sphere-field.json", 32, 4);
  ASSERT_EQ(points[0].scene.spheres.size(), 1024u);
  const std::vector<Method> methods = {Method::HtVis, Method::HtFrontier, Method::HtCut};
  const double zCrit =
      normalQuantileTwoSided(1.0 - std::pow(1.0 - 0.01, 1.0 / double(methods.size() * points.size())));
  const MethodTables cutTables = prepareTables(points[0].scene, Method::HtCut);
  int onPlane = 0;
  for (const ShadingSetup& p : points) {
    EXPECT_EQ(occluders(p.scene, p.sp).size(), kMaxCaps) << p.name;
    ASSERT_EQ(occluders(p.scene, p.sp, kCutMaxCaps).size(), kCutMaxCaps) << p.name;
    ShadingPoint sp = p.sp;
    sp.material = &p.scene.materials[0];
    EstimateCounters counters;
    const Shading sh(p.scene, sp, counters);
    const CutPoint cut(p.scene, sp, sh, CutOptions{}, cutTables.own<EnvCut>(), cutTables.geometry());
    const Plane& ground = p.scene.planes[0];
    const bool flat = std::abs(glm::dot(p.sp.position - ground.point, ground.normal)) < 1e-3f;
    onPlane += flat;
    EXPECT_EQ(size_t(cut.caps.count), kCutMaxCaps - (flat ? 1 : 0)) << p.name;
    const double ref = bruteForceIntegral(p, 12).g;
    const double refError = std::abs(ref - bruteForceIntegral(p, 6).g);
    for (Method m : methods) {
      const MeanAndError e = repeatedEstimates(p, m, 2000, 8, 77, {});
      const double se = std::sqrt(e.stdError.g * e.stdError.g + refError * refError);
      EXPECT_LT(std::abs(e.mean.g - ref) / se, zCrit)
          << p.name << " / " << methodName(m) << ": mean " << e.mean.g << " reference " << ref;
    }
  }
  EXPECT_GT(onPlane, 0);
  EXPECT_LT(onPlane, int(points.size()));
}
