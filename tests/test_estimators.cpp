// Unbiasedness and furnace tests of the baseline estimators.
#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include "estimator_harness.h"
#include "image_io.h"

using namespace ht;
using namespace ht::test;

namespace {

constexpr int kEnvOrder = 5;  // Nside 32: brute force over all pixels stays cheap

const Environment& sunriseEnvironment() {
  static const Environment env = sunriseAt(kEnvOrder);
  return env;
}

Environment onePixelSun(float background = 0.02f) { return test::onePixelSun(kEnvOrder, background); }

// The baselines, unbiased HT and the HT frontier. The biased variants and
// the competitors (wis, tsis, ris) have their own tests; the brute-force
// oracle is too slow for these sample counts (tested below).
std::vector<MethodSpec> unbiasedMethods() {
  std::vector<MethodSpec> methods;
  for (const MethodSpec& m : allMethods())
    if (!m.biased && (m.family == Family::Baseline || m.family == Family::Ht || m.family == Family::Product))
      methods.push_back(m);
  return methods;
}

std::vector<ShadingSetup> unbiasednessSetups() {
  std::vector<ShadingSetup> s;
  s.push_back(makeSetup("diffuse-sunrise", sunriseEnvironment(), lambert(0.8f), {0.3f, 1.0f, 0.2f}));
  s.push_back(makeSetup("ggx0.2-sunrise", sunriseEnvironment(), ggx(0.2f, glm::vec3(0.9f, 0.7f, 0.4f)),
                        {0.2f, 0.5f, -0.8f}));
  s.push_back(makeSetup("phong-sunrise-occluded", sunriseEnvironment(), phong(40.0f, glm::vec3(0.4f), glm::vec3(0.3f)),
                        {-0.4f, 0.6f, 0.3f}, {{glm::vec3(-1.0f, 1.0f, 0.5f), 0.8f, 0}}));
  s.push_back(makeSetup("diffuse-sun", onePixelSun(), lambert(0.8f), {0.0f, 1.0f, 0.3f}));
  s.push_back(makeSetup("ggx0.3-sun", onePixelSun(), ggx(0.3f, glm::vec3(0.04f), glm::vec3(0.5f)), mirrorOf(kSunDir)));
  s.push_back(makeSetup("diffuse-sun-shadowed", onePixelSun(), lambert(0.8f), {0.0f, 1.0f, 0.3f},
                        {{2.0f * kSunDir, 0.4f, 0}}));
  s.push_back(makeSetup("ggx0.25-grazing-sunrise", sunriseEnvironment(), ggx(0.25f, glm::vec3(0.95f)),
                        {std::sin(1.48f), std::cos(1.48f), 0.0f}));
  return s;
}

}  // namespace

// Every method's mean over many independent estimates matches the brute-force
// integral by a z-test (Sidak-corrected over setups, methods and channels);
// the brute force's own error, measured by halving its grid, enters the
// standard error.
TEST(Estimators, UnbiasedAgainstBruteForce) {
  const std::vector<ShadingSetup> setups = unbiasednessSetups();
  const std::vector<MethodSpec> methods = unbiasedMethods();
  const int tests = int(setups.size() * methods.size() * 3);
  const double zCrit = normalQuantileTwoSided(1.0 - std::pow(1.0 - 0.01, 1.0 / tests));
  for (const ShadingSetup& s : setups) {
    glm::dvec3 ref = bruteForceIntegral(s, 16);
    glm::dvec3 coarse = bruteForceIntegral(s, 8);
    glm::dvec3 refError = glm::abs(ref - coarse);
    ASSERT_GT(ref.g, 0.0) << s.name;
    EXPECT_LT(refError.g, 1e-2 * ref.g) << s.name << ": brute force not converged";
    for (const MethodSpec& m : methods) {
      MeanAndError e = repeatedEstimates(s, m.method, 40000, 32, 1234);
      for (int c = 0; c < 3; ++c) {
        double se = std::sqrt(e.stdError[c] * e.stdError[c] + refError[c] * refError[c]);
        double z = std::abs(e.mean[c] - ref[c]) / se;
        EXPECT_LT(z, zCrit) << s.name << " / " << m.name << " channel " << c << ": mean " << e.mean[c]
                            << " reference " << ref[c] << " std error " << e.stdError[c];
      }
    }
  }
}

// White furnace: L = 1 everywhere, Lambert albedo a, nothing in the way:
// Lo = a. Cosine and BRDF sampling are then exact for every sample, and so
// is mis-compensated, which a constant map leaves with BRDF sampling alone.
TEST(Estimators, WhiteFurnace) {
  const int tests = 2 * int(unbiasedMethods().size());
  const double zCrit = normalQuantileTwoSided(1.0 - std::pow(1.0 - 0.01, 1.0 / tests));
  for (float albedo : {0.3f, 0.8f}) {
    ShadingSetup s = makeSetup("furnace", constantEnvironment(3, glm::vec3(1.0f)), lambert(albedo), {0.4f, 0.7f, -0.2f});
    for (const MethodSpec& m : unbiasedMethods()) {
      MeanAndError e = repeatedEstimates(s, m.method, 20000, 4, 99);
      if (m.method == Method::Cosine || m.method == Method::Brdf || m.method == Method::MisCompensated) {
        EXPECT_NEAR(e.mean.g, albedo, 1e-5 * albedo) << m.name;
        EXPECT_LT(e.stdError.g, 1e-6) << m.name << ": should have zero variance";
      } else {
        ASSERT_GT(e.stdError.g, 0.0) << m.name;
        EXPECT_LT(std::abs(e.mean.g - albedo) / e.stdError.g, zCrit) << m.name << " mean " << e.mean.g;
      }
    }
  }
}

// With a single lit pixel, environment sampling always picks it: its only
// variance is f cos varying inside one pixel (about 0.03 rad across at
// Nside 32), while BRDF and cosine sampling rarely find it.
TEST(Estimators, EnvironmentSamplingFindsASinglePixelSun) {
  ShadingSetup s = makeSetup("sun-only", onePixelSun(0.0f), lambert(0.8f), {0.0f, 1.0f, 0.3f});
  const double exact = bruteForceIntegral(s, 8).g;
  auto relStd = [&](Method m) {
    const int n = 200000;
    MeanAndError e = repeatedEstimates(s, m, n, 1, 5);
    return e.stdError.g * std::sqrt(double(n)) / exact;
  };
  EXPECT_LT(relStd(Method::Env), 0.05);
  EXPECT_GT(relStd(Method::Cosine), 1.0);
  EXPECT_GT(relStd(Method::Brdf), 1.0);
}

// An all-black environment gives exactly zero, never NaN.
TEST(Estimators, BlackEnvironmentIsZero) {
  ShadingSetup s = makeSetup("black", constantEnvironment(2, glm::vec3(0.0f)), ggx(0.3f, glm::vec3(0.5f), glm::vec3(0.5f)),
                      {0.0f, 1.0f, 0.3f});
  for (const MethodSpec& m : allMethods()) {
    if (!m.estimate) continue;  // whole images only (test_restir.cpp)
    MeanAndError e = repeatedEstimates(s, m.method, 100, 4, 1);
    EXPECT_EQ(e.mean, glm::dvec3(0.0)) << m.name;
  }
}

// The oracle (brute-force product at a coarse level, refined per sample by
// point evaluations) is unbiased: its unresolved share reaches the lit
// slivers of nodes whose points are all dark.
TEST(Estimators, OracleUnbiased) {
  std::vector<ShadingSetup> setups = unbiasednessSetups();
  const double zCrit = normalQuantileTwoSided(1.0 - std::pow(1.0 - 0.01, 1.0 / (3.0 * setups.size())));
  MethodOptions options;
  options.oracleOrder = 3;
  for (const ShadingSetup& s : setups) {
    glm::dvec3 ref = bruteForceIntegral(s, 16);
    glm::dvec3 refError = glm::abs(ref - bruteForceIntegral(s, 8));
    for (SamplerKind kind : {SamplerKind::Stratified, SamplerKind::Independent}) {
      options.sampler = kind;
      MeanAndError oracle = repeatedEstimates(s, Method::Oracle, 3000, 4, 31, options);
      for (int c = 0; c < 3; ++c) {
        double se = std::sqrt(oracle.stdError[c] * oracle.stdError[c] + refError[c] * refError[c]);
        EXPECT_LT(std::abs(oracle.mean[c] - ref[c]) / se, zCrit)
            << s.name << " channel " << c << " sampler " << int(kind) << ": " << oracle.mean[c] << " against " << ref[c]
            << " (se " << se << ")";
      }
    }
  }
}

// The oracle is the floor the other samplers are judged against: tabulated at
// the environment's resolution, the variance of its luminance estimate is
// less than half that of mis and of ht-vis at equal spp, for a lobe narrower
// than the environment's pixels and a point in a sphere's shadow too. (All
// of them sample by luminance, so colour noise is left out.)
TEST(EstimatorsSlow, OracleIsTheVarianceFloor) {
  std::vector<ShadingSetup> setups;
  setups.push_back(makeSetup("diffuse-sunrise", sunriseEnvironment(), lambert(0.8f), {0.3f, 1.0f, 0.2f}));
  setups.push_back(makeSetup("ggx0.2-sunrise", sunriseEnvironment(), ggx(0.2f, glm::vec3(0.9f, 0.7f, 0.4f)),
                             {0.2f, 0.5f, -0.8f}));
  setups.push_back(makeSetup("ggx0.02-sunrise", sunriseEnvironment(), ggx(0.02f, glm::vec3(0.95f)), {0.2f, 0.5f, -0.8f}));
  setups.push_back(makeSetup("diffuse-sun-shadowed", onePixelSun(), lambert(0.8f), {0.0f, 1.0f, 0.3f},
                             {{2.0f * kSunDir, 0.4f, 0}}));
  MethodOptions options;
  options.oracleOrder = kEnvOrder;
  for (const ShadingSetup& s : setups) {
    double oracle = repeatedEstimates(s, Method::Oracle, 2000, 4, 41, options).luminanceVariance;
    for (Method m : {Method::Mis, Method::HtVis}) {
      double other = repeatedEstimates(s, m, 2000, 4, 41, options).luminanceVariance;
      EXPECT_LT(oracle, 0.5 * other) << s.name << " against " << allMethods()[size_t(m)].name;
    }
  }
}
