// Every sampler's directions against its own density: chi-square goodness of
// fit on equal-area HEALPix bins, Sidak-corrected over all cases.
#include <gtest/gtest.h>

#include <functional>
#include <memory>
#include <random>

#include "bsdf.h"
#include "chi2.h"
#include "env_sampler.h"
#include "image_io.h"
#include "rng.h"
#include "sampling.h"

using namespace ht;
using namespace ht::test;

namespace {

using Case = DensityCase;

glm::vec3 dirFromAngle(float thetaDeg) {
  float t = thetaDeg * kPi / 180.0f;
  return {std::sin(t), 0.0f, std::cos(t)};
}

Case bsdfCase(std::string name, Material m, float thetaDeg) {
  glm::vec3 wo = dirFromAngle(thetaDeg);
  return {std::move(name),
          [m, wo](Rng& rng) { return glm::dvec3(sampleBsdf(m, wo, rng.next2())); },
          [m, wo](glm::dvec3 d) { return double(bsdfPdf(m, wo, glm::vec3(d))); }, 5};
}

Material makeMaterial(MaterialType type, glm::vec3 diffuse, glm::vec3 specular, float exponent, float alpha) {
  Material m;
  m.type = type;
  m.diffuse = diffuse;
  m.specular = specular;
  m.exponent = exponent;
  m.alpha = alpha;
  return m;
}

const Environment& sunrise() {
  static const Environment env = [] {
    ImageRGB img = readExr(std::string(HT_TEST_DATA) + "/env/sunrise.exr");
    sanitizeEnvironmentImage(img, "sunrise.exr");
    return environmentFromEquirect(img, 4, 30.0f, 1.0f);
  }();
  return env;
}

const Environment& sunAndSky() {
  static const Environment env = [] {
    std::vector<glm::vec3> px(healpix::pixelCount(4), glm::vec3(0.05f));
    for (uint64_t p = 0; p < px.size() / 2; ++p) px[p] = glm::vec3(0.0f);  // a black region
    px[1234] = glm::vec3(5000.0f);
    return environmentFromPixels(4, std::move(px));
  }();
  return env;
}

// Bins are the environment's own pixels: the density is constant on each.
Case envCase(std::string name, const Environment& env) {
  return {std::move(name), [&env](Rng& rng) { return env.toHealpixFrame(sampleEnvironment(env, rng.next2Precise()).dir); },
          [&env](glm::dvec3 d) { return double(environmentPdf(env, env.fromHealpixFrame(d))); }, env.order};
}

// mis-compensated's environment technique: the density of max(0, L - mean L).
Case compensatedCase(std::string name, const Environment& env) {
  auto tree = std::make_shared<const MaxAvgTree>(compensatedTree(env));
  return {std::move(name),
          [&env, tree](Rng& rng) { return env.toHealpixFrame(sampleEnvironment(env, *tree, rng.next2Precise()).dir); },
          [&env, tree](glm::dvec3 d) { return double(environmentPdf(env, *tree, env.fromHealpixFrame(d))); },
          env.order};
}

std::vector<Case> cases() {
  std::vector<Case> c;
  c.push_back({"uniform-sphere", [](Rng& r) { return glm::dvec3(sampleUniformSphere({r.next(), r.next()})); },
               [](glm::dvec3) { return double(uniformSpherePdf()); }, 3});
  c.push_back({"cosine-hemisphere", [](Rng& r) { return glm::dvec3(sampleCosineHemisphere({r.next(), r.next()})); },
               [](glm::dvec3 d) { return double(cosineHemispherePdf(float(d.z))); }, 4});
  c.push_back({"power-cosine-50", [](Rng& r) { return glm::dvec3(samplePowerCosine({r.next(), r.next()}, 50.0f)); },
               [](glm::dvec3 d) { return double(powerCosinePdf(float(d.z), 50.0f)); }, 5});
  const glm::vec3 grey(0.5f), none(0.0f);
  c.push_back(bsdfCase("lambert", makeMaterial(MaterialType::Lambert, grey, none, 1, 1), 30));
  c.push_back(bsdfCase("phong-20-diffuse", makeMaterial(MaterialType::Phong, grey, glm::vec3(0.4f), 20, 1), 30));
  c.push_back(bsdfCase("phong-300-grazing", makeMaterial(MaterialType::Phong, none, glm::vec3(0.9f), 300, 1), 80));
  c.push_back(bsdfCase("ggx-0.5", makeMaterial(MaterialType::Ggx, none, glm::vec3(0.9f), 1, 0.5f), 40));
  c.push_back(bsdfCase("ggx-0.1-diffuse", makeMaterial(MaterialType::Ggx, grey, glm::vec3(0.04f), 1, 0.1f), 20));
  c.push_back(bsdfCase("ggx-0.05-grazing", makeMaterial(MaterialType::Ggx, none, glm::vec3(0.9f), 1, 0.05f), 85));
  c.push_back(envCase("env-sunrise", sunrise()));
  c.push_back(envCase("env-sun-black-half", sunAndSky()));
  c.push_back(compensatedCase("env-compensated-sunrise", sunrise()));
  c.push_back(compensatedCase("env-compensated-sun-black-half", sunAndSky()));
  return c;
}

}  // namespace

TEST(Samplers, ChiSquareAgainstOwnPdf) { expectDensitiesMatch(cases(), 7, 0); }

// The density a sampler reports with a sample is its pdf at that direction.
TEST(Samplers, EnvironmentSamplePdfEqualsPdfOfDirection) {
  for (const Environment* env : {&sunrise(), &sunAndSky()}) {
    Rng rng(3, 0);
    int mismatches = 0;
    for (int i = 0; i < 100000; ++i) {
      EnvSample s = sampleEnvironment(*env, rng.next2Precise());
      ASSERT_GT(s.pdf, 0.0f);
      float p = environmentPdf(*env, s.dir);
      // A float direction may round onto a neighbouring pixel's border.
      if (std::abs(p - s.pdf) > 1e-5f * s.pdf) ++mismatches;
    }
    EXPECT_LE(mismatches, 10);
  }
}

// Exact samplers: f cos / pdf is constant (the albedo) for every sample.
TEST(Samplers, LambertBrdfSamplingIsExact) {
  Material m = makeMaterial(MaterialType::Lambert, glm::vec3(0.7f), glm::vec3(0.0f), 1, 1);
  glm::vec3 wo = dirFromAngle(50);
  Rng rng(11, 0);
  for (int i = 0; i < 10000; ++i) {
    glm::vec3 wi = sampleBsdf(m, wo, rng.next2());
    float pdf = bsdfPdf(m, wo, wi);
    if (wi.z <= 1e-4f) continue;
    ASSERT_NEAR(evalBsdf(m, wo, wi).g / pdf, 0.7f, 1e-4f);
  }
}

// GGX visible-normal sampling: f cos / pdf = F G2 / G1(wo), at most F.
TEST(Samplers, GgxWeightIsBoundedByFresnel) {
  Material m = makeMaterial(MaterialType::Ggx, glm::vec3(0.0f), glm::vec3(1.0f), 1, 0.3f);
  glm::vec3 wo = dirFromAngle(60);
  Rng rng(12, 0);
  int above = 0;
  for (int i = 0; i < 10000; ++i) {
    glm::vec3 wi = sampleBsdf(m, wo, rng.next2());
    if (wi.z <= 0.0f) continue;
    ++above;
    float w = evalBsdf(m, wo, wi).g / bsdfPdf(m, wo, wi);
    ASSERT_LE(w, 1.0f + 1e-4f);
    ASSERT_GT(w, 0.0f);
  }
  EXPECT_GT(above, 9000);
}
