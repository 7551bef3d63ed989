// The samplers HT is compared against: resampled importance sampling (ris),
// two-stage importance sampling (tsis) and wavelet importance sampling (wis,
// wis-biased). Each sampler's directions against its own density
// (chi-square), each estimator's mean against a brute-force integral
// (z-tests, Sidak-corrected), and the properties that make them what they
// are (exact density bookkeeping, stratification, convergence of RIS to its
// target, wis-biased's error against the WIS resolution).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>

#include <glm/geometric.hpp>

#include "chi2.h"
#include "env_sampler.h"
#include "estimator_harness.h"
#include "healpix.h"
#include "image_io.h"
#include "ris.h"
#include "tsis.h"
#include "wis.h"

using namespace ht;
using namespace ht::test;

namespace {

std::shared_ptr<const TsisTable> tsisTableOf(const Environment& env, int level = TsisTable::kMaxLevel) {
  return std::make_shared<const TsisTable>(buildTsisTable(env, level));
}

// wis node centres of an order, built once per test process.
const std::vector<glm::vec3>& centersOf(int order) {
  static std::map<int, std::vector<glm::vec3>> built;
  auto [it, added] = built.try_emplace(order);
  if (added) it->second = healpixNodeCenters(order);
  return it->second;
}

constexpr int kEnvOrder = 5;  // Nside 32: brute force over all pixels stays cheap

const Environment& sunrise() {
  static const Environment env = sunriseAt(kEnvOrder);
  return env;
}

Environment onePixelSun(float background = 0.02f, bool blackHalf = false) {
  return test::onePixelSun(kEnvOrder, background, blackHalf);
}

// Shading points on the plane y = 0 (normal +y) as in test_estimators.cpp:
// a small sun with a glossy lobe, a sun shadowed by a sphere, an occluded
// Phong lobe under a real map, a sharp GGX lobe, a grazing view.
std::vector<ShadingSetup> unbiasednessSetups() {
  std::vector<ShadingSetup> s;
  s.push_back(makeSetup("ggx0.3-sun", onePixelSun(), ggx(0.3f, glm::vec3(0.04f), glm::vec3(0.5f)), mirrorOf(kSunDir)));
  s.push_back(makeSetup("diffuse-sun-shadowed", onePixelSun(), lambert(0.8f), {0.0f, 1.0f, 0.3f},
                        {{2.0f * kSunDir, 0.4f, 0}}));
  s.push_back(makeSetup("phong-sunrise-occluded", sunrise(), phong(40.0f, glm::vec3(0.4f), glm::vec3(0.3f)),
                        {-0.4f, 0.6f, 0.3f}, {{glm::vec3(-1.0f, 1.0f, 0.5f), 0.8f, 0}}));
  s.push_back(makeSetup("ggx0.08-sunrise", sunrise(), ggx(0.08f, glm::vec3(1.0f, 0.78f, 0.34f)), {0.2f, 0.5f, -0.8f}));
  s.push_back(makeSetup("ggx0.25-grazing-sunrise", sunrise(), ggx(0.25f, glm::vec3(0.95f)),
                        {std::sin(1.48f), std::cos(1.48f), 0.0f}));
  return s;
}

struct Reference {
  glm::dvec3 value;
  glm::dvec3 error;  // |fine - coarse| brute force: the reference's own error
};

// Brute-force integrals, computed once per setup name.
const Reference& reference(const ShadingSetup& s) {
  static std::map<std::string, Reference> cache;
  auto it = cache.find(s.name);
  if (it != cache.end()) return it->second;
  Reference r;
  r.value = bruteForceIntegral(s, 12);
  r.error = glm::abs(r.value - bruteForceIntegral(s, 6));
  return cache.emplace(s.name, r).first->second;
}

// --- chi-square of the samplers against their own densities ---------------

// A density case in world space, its bins in the HEALPix frame of `env`.
struct WorldDensityCase {
  std::string name;
  std::function<glm::vec3(Rng&)> sample;  // world direction
  std::function<double(glm::vec3)> pdf;   // of a world direction
  const Environment* env;                 // bins are pixels of its HEALPix frame
  int binOrder;
  int subdiv;  // midpoint rule per bin for the expected counts
  int samples;
};

void runChiSquare(const std::vector<WorldDensityCase>& all) {
  std::vector<DensityCase> cases;
  for (const WorldDensityCase& c : all) {
    const Environment& env = *c.env;
    cases.push_back({c.name, [&env, sample = c.sample](Rng& rng) { return env.toHealpixFrame(sample(rng)); },
                     [&env, pdf = c.pdf](glm::dvec3 d) { return pdf(env.fromHealpixFrame(d)); }, c.binOrder,
                     c.subdiv, c.samples});
  }
  expectDensitiesMatch(cases, 17, 0);
}

// The shading frames of the density cases: a normal that is not the map's
// pole, so that no face or pixel border lines up with the horizon.
const glm::vec3 kTiltedNormal = glm::normalize(glm::vec3(0.3f, 1.0f, -0.2f));

glm::vec3 viewAt(const glm::vec3& n, float thetaDeg) {
  Frame f(n);
  float t = thetaDeg * kPi / 180.0f;
  return f.toWorld({std::sin(t), 0.0f, std::cos(t)});
}

}  // namespace

// Warped directions follow the density each sampler reports for any
// direction, for single uniform points and for the stratified point sets the
// estimators use (those only make the counts less dispersed).
TEST(Competitors, ChiSquareAgainstOwnPdf) {
  static const Environment sunHalf = onePixelSun(0.05f, true);
  const Material gloss = ggx(0.2f, glm::vec3(0.9f, 0.7f, 0.4f), glm::vec3(0.1f));
  const Material sharp = phong(200.0f, glm::vec3(0.6f), glm::vec3(0.2f));
  const Material chalk = lambert(0.8f);
  const glm::vec3 n = kTiltedNormal;
  std::vector<WorldDensityCase> cases;

  auto tsis = [&](std::string name, const Environment& env, const Material& m, float view, int regions, int satLevel,
                  int sets) {
    auto p = std::make_shared<TsisPoint>(env, tsisTableOf(env, satLevel), m, n, viewAt(n, view), regions);
    const int count = 300000;
    std::function<glm::vec3(Rng&)> sample = [p](Rng& rng) {
      return p->warp({double(rng.next()) + 0x1p-24 * rng.next(), double(rng.next()) + 0x1p-24 * rng.next()}).dir;
    };
    if (sets > 1) {  // `sets` points of one pixel's stratified sampler, consecutive draws share it
      auto state = std::make_shared<std::pair<int, PixelSampler>>(0, PixelSampler(SamplerKind::Stratified, 0u));
      sample = [p, state, sets](Rng& rng) {
        if (state->first % sets == 0) state->second = PixelSampler(SamplerKind::Stratified, rng.nextUint());
        state->second.startSample(uint32_t(state->first++ % sets));
        return p->warp(state->second.get2DPrecise()).dir;
      };
    }
    cases.push_back({std::move(name), sample, [p](glm::vec3 d) { return p->pdf(d); }, &env, env.order, 2, count});
  };
  tsis("tsis-ggx-sunrise", sunrise(), gloss, 40, TsisPoint::kDefaultRegions, TsisTable::kMaxLevel, 1);
  tsis("tsis-phong-sun-black-half-grazing", sunHalf, sharp, 80, 16, TsisTable::kMaxLevel, 1);
  tsis("tsis-lambert-sunrise-sat-level-3", sunrise(), chalk, 10, 64, 3, 1);
  tsis("tsis-ggx-sunrise-stratified-sets", sunrise(), gloss, 40, TsisPoint::kDefaultRegions, TsisTable::kMaxLevel, 16);

  auto wis = [&](std::string name, const Environment& env, const Material& m, float view, int order, int sets) {
    auto p = std::make_shared<WisPoint>(env, m, n, viewAt(n, view), order,
                                        centersOf(WisPoint::orderFor(env, order)));
    const int count = 300000;
    std::function<glm::vec3(Rng&)> sample = [p](Rng& rng) {
      return p->warp({double(rng.next()) + 0x1p-24 * rng.next(), double(rng.next()) + 0x1p-24 * rng.next()}).dir;
    };
    if (sets > 1) {
      auto state = std::make_shared<std::pair<int, PixelSampler>>(0, PixelSampler(SamplerKind::Stratified, 0u));
      sample = [p, state, sets](Rng& rng) {
        if (state->first % sets == 0) state->second = PixelSampler(SamplerKind::Stratified, rng.nextUint());
        state->second.startSample(uint32_t(state->first++ % sets));
        return p->warp(state->second.get2DPrecise()).dir;
      };
    }
    // The density is constant on the pixels of the WIS order: bins one level finer.
    const int binOrder = std::min(p->order() + 1, 5);
    cases.push_back({std::move(name), sample, [p](glm::vec3 d) { return p->pdf(d); }, &env, binOrder, 2, count});
  };
  wis("wis-5-ggx-sunrise", sunrise(), gloss, 40, 5, 1);
  wis("wis-3-ggx-sunrise", sunrise(), gloss, 40, 3, 1);
  wis("wis-4-phong-sun-black-half-grazing", sunHalf, sharp, 80, 4, 1);
  wis("wis-2-lambert-sunrise-stratified-sets", sunrise(), chalk, 10, 2, 16);

  // RIS candidates follow the mixture of env and BRDF sampling (with one
  // candidate, RIS keeps it: RisWithOneCandidateIsTheMixture).
  auto ris = [&](std::string name, const Environment& env, const Material& m, float view) {
    auto p = std::make_shared<RisSampler>(env, m, n, viewAt(n, view));
    cases.push_back({std::move(name), [p](Rng& rng) { return p->candidate(rng.next2Precise()).dir; },
                     [p](glm::vec3 d) { return double(p->mixturePdf(d)); }, &env, 5, 12, 500000});
  };
  ris("ris-m1-ggx-sunrise", sunrise(), gloss, 40);
  ris("ris-m1-phong-sun-black-half-grazing", sunHalf, sharp, 80);

  runChiSquare(cases);
}

// With M = 1, RIS keeps its one candidate whenever the target is positive there,
// with the contribution weight 1 / p_mix: it is the mixture sampler, whose
// candidates pass the chi-square test above.
TEST(Competitors, RisWithOneCandidateIsTheMixture) {
  const Material gloss = ggx(0.2f, glm::vec3(0.9f, 0.7f, 0.4f), glm::vec3(0.1f));
  const glm::vec3 n = kTiltedNormal;
  RisSampler ris(sunrise(), gloss, n, viewAt(n, 60));
  int kept = 0;
  for (uint32_t i = 0; i < 20000; ++i) {
    PixelSampler a(SamplerKind::Independent, 8), b(SamplerKind::Independent, 8);
    a.startSample(i);
    const RisCandidate c = ris.candidate(a.get2DPrecise());
    const RisSample s = ris.sample(1, b, i);
    if (c.target > 0.0f) {
      ++kept;
      ASSERT_EQ(s.chosen.dir, c.dir);
      ASSERT_NEAR(s.contributionWeight() * c.mixturePdf, 1.0, 1e-6);
      ASSERT_NEAR(c.mixturePdf, ris.mixturePdf(c.dir), 1e-4 * c.mixturePdf + 1e-7);
      ASSERT_NEAR(c.target, ris.target(c.dir), 1e-4 * c.target + 1e-9);
    } else {
      ASSERT_EQ(s.contributionWeight(), 0.0);
    }
  }
  EXPECT_GT(kept, 10000);
}

// The density returned with a sample is the density of its direction, and
// summed over all pixels the pixel probabilities are one.
TEST(Competitors, SampleDensityMatchesDensityOfDirection) {
  const Material gloss = ggx(0.15f, glm::vec3(0.9f), glm::vec3(0.2f));
  const glm::vec3 n = kTiltedNormal, wo = viewAt(n, 50);
  for (int satLevel : {TsisTable::kMaxLevel, 2}) {
    TsisPoint t(sunrise(), tsisTableOf(sunrise(), satLevel), gloss, n, wo, 40);
    ASSERT_FALSE(t.empty());
    // The regions tile the twelve faces.
    uint64_t covered = 0;
    double prob = 0.0;
    for (const TsisRegion& r : t.regions()) {
      covered += uint64_t(r.x1 - r.x0) * (r.y1 - r.y0);
      prob += r.probability;
    }
    EXPECT_EQ(covered, healpix::pixelCount(t.table().level));
    EXPECT_NEAR(prob, 1.0, 1e-12);
    EXPECT_LE(t.regions().size(), 40u);
    EXPECT_GT(t.regions().size(), 12u) << "no BRDF-driven split";
    Rng rng(5, 0);
    int mismatches = 0;
    for (int i = 0; i < 20000; ++i) {
      TsisSample s = t.warp({rng.next(), rng.next()});
      ASSERT_GT(s.pdf, 0.0);
      if (std::abs(t.pdf(s.dir) - s.pdf) > 1e-6 * s.pdf) ++mismatches;
    }
    EXPECT_LE(mismatches, 10) << "sat level " << satLevel;
  }
  for (int order : {0, 3, 5}) {
    WisPoint w(sunrise(), gloss, n, wo, order, centersOf(order));
    ASSERT_EQ(w.order(), order);
    double total = 0.0;
    for (uint64_t p = 0; p < healpix::pixelCount(order); ++p) total += w.pixelProbability(p);
    EXPECT_NEAR(total, 1.0, 1e-9) << "order " << order;
    Rng rng(6, 0);
    int mismatches = 0, elsewhere = 0;
    for (int i = 0; i < 20000; ++i) {
      WisSample s = w.warp({rng.next(), rng.next()});
      ASSERT_GT(s.pdf, 0.0);
      // A float direction may round onto a neighbouring pixel's border.
      if (healpix::vecToPix(order, sunrise().toHealpixFrame(s.dir)) != s.pixel) ++elsewhere;
      if (std::abs(w.pdf(s.dir) - s.pdf) > 1e-9 * s.pdf) ++mismatches;
    }
    EXPECT_LE(elsewhere, 10) << "order " << order;
    EXPECT_LE(mismatches, 10) << "order " << order;
  }
  // The WIS order is clamped to the map's.
  EXPECT_EQ(WisPoint(sunrise(), gloss, n, wo, 9, centersOf(kEnvOrder)).order(), kEnvOrder);
}

// Each estimator's mean over many independent estimates matches the brute
// force (z-tests, Sidak-corrected over setups, configurations and channels).
// wis-biased has a known expectation too: the integral of its approximated
// product, sum over WIS pixels of (env average x f cos at the centre) x solid
// angle, where nothing is in the way.
TEST(Competitors, UnbiasedAgainstBruteForce) {
  struct Config {
    std::string name;
    Method method;
    MethodOptions options;
    int batches, spp;
  };
  std::vector<Config> configs;
  MethodOptions o;
  configs.push_back({"ris M=32", Method::Ris, o, 4000, 4});
  o.risCandidates = 3;
  configs.push_back({"ris M=3", Method::Ris, o, 8000, 8});
  o = {};
  configs.push_back({"tsis", Method::Tsis, o, 8000, 16});
  configs.push_back({"wis order 5", Method::Wis, o, 8000, 16});
  o.wisOrder = 3;
  configs.push_back({"wis order 3", Method::Wis, o, 8000, 16});

  const std::vector<ShadingSetup> setups = unbiasednessSetups();
  const int tests = int(setups.size() * configs.size() * 3) + 3;
  const double zCrit = normalQuantileTwoSided(sidakAlpha(0.01, tests));
  auto check = [&](const std::string& what, const MeanAndError& e, glm::dvec3 ref, glm::dvec3 refError) {
    for (int c = 0; c < 3; ++c) {
      double se = std::sqrt(e.stdError[c] * e.stdError[c] + refError[c] * refError[c]);
      ASSERT_GT(se, 0.0) << what;
      EXPECT_LT(std::abs(e.mean[c] - ref[c]) / se, zCrit)
          << what << " channel " << c << ": mean " << e.mean[c] << " reference " << ref[c] << " std error "
          << e.stdError[c];
    }
  };
  for (const ShadingSetup& s : setups) {
    const Reference& ref = reference(s);
    ASSERT_GT(ref.value.g, 0.0) << s.name;
    EXPECT_LT(ref.error.g, 1e-2 * ref.value.g) << s.name << ": brute force not converged";
    for (const Config& c : configs) {
      MeanAndError e = repeatedEstimates(s, c.method, c.batches, c.spp, 2024, c.options);
      check(s.name + " / " + c.name, e, ref.value, ref.error);
    }
  }

  // wis-biased against its own expectation (unoccluded setup).
  const ShadingSetup& s = setups[3];
  MethodOptions wo;
  wo.wisOrder = 4;
  WisPoint w(s.scene.environment, s.scene.materials[0], s.sp.normal, s.sp.wo, wo.wisOrder, centersOf(wo.wisOrder));
  glm::dvec3 expectation(0.0);
  for (uint64_t p = 0; p < healpix::pixelCount(wo.wisOrder); ++p)
    expectation += glm::dvec3(w.approximateProduct(p)) * healpix::pixelSolidAngle(wo.wisOrder);
  MeanAndError e = repeatedEstimates(s, Method::WisBiased, 4000, 16, 77, wo);
  check(s.name + " / wis-biased expectation", e, expectation, glm::dvec3(0.0));
}

// wis-biased converges as the WIS order rises: its error against the brute
// force falls from order to order (a one-sided z-test per step, Sidak over
// the four steps). The step from order 3 to 4 is small here (about 5.4 % to
// 4.7 %), hence the many estimates.
TEST(Competitors, WisBiasedErrorFallsWithOrder) {
  const ShadingSetup s = makeSetup("ggx0.2-sunrise", sunrise(), ggx(0.2f, glm::vec3(0.9f, 0.7f, 0.4f)),
                                   {0.2f, 0.5f, -0.8f}, {{glm::vec3(-1.0f, 1.0f, 0.5f), 0.8f, 0}});
  const Reference& ref = reference(s);
  const double zCrit = normalQuantileTwoSided(2.0 * (1.0 - std::pow(1.0 - 0.01, 1.0 / 4.0)));  // one-sided
  double previous = INFINITY, previousSe = 0.0;
  for (int order : {1, 2, 3, 4, 5}) {
    MethodOptions o;
    o.wisOrder = order;
    MeanAndError e = repeatedEstimates(s, Method::WisBiased, 20000, 16, 9, o);
    const double err = std::abs(e.mean.g - ref.value.g) / ref.value.g;
    const double se = (e.stdError.g + ref.error.g) / ref.value.g;
    std::printf("wis-biased order %d: relative error %.4f (+- %.4f)\n", order, err, se);
    if (order > 1) {
      EXPECT_GT((previous - err) / std::sqrt(se * se + previousSe * previousSe), zCrit) << "order " << order;
    }
    previous = err;
    previousSe = se;
  }
}

// RIS converges to its target: with more candidates the kept direction's
// distribution h approaches t = p_hat / integral of p_hat. Measured on
// equal-area bins by the Pearson divergence sum (h - t)^2 / t, less its
// expected sampling noise, which falls like 1/M; with one candidate (the
// mixture) it is far from zero.
TEST(Competitors, RisApproachesTargetAsCandidatesGrow) {
  const Environment& env = sunrise();
  const Material m = ggx(0.2f, glm::vec3(0.9f, 0.7f, 0.4f));
  const glm::vec3 n = kTiltedNormal;
  RisSampler ris(env, m, n, viewAt(n, 40));
  constexpr int kBinOrder = 2;
  std::vector<double> target = expectedCountsHealpix(
      kBinOrder, 16, [&](glm::dvec3 d) { return double(ris.target(env.fromHealpixFrame(d))); }, 1.0);
  double norm = 0.0;
  for (double t : target) norm += t;
  for (double& t : target) t /= norm;
  auto divergence = [&](int candidates, int samples) {
    std::vector<double> hist(target.size(), 0.0);
    PixelSampler sampler(SamplerKind::Independent, 21 + uint32_t(candidates));
    int kept = 0;
    for (int i = 0; i < samples; ++i) {
      RisSample s = ris.sample(candidates, sampler, uint32_t(i));
      if (!(s.contributionWeight() > 0.0)) continue;
      ++kept;
      hist[binIndex(kBinOrder, env.toHealpixFrame(s.chosen.dir))] += 1.0;
    }
    double d = 0.0;
    for (size_t b = 0; b < hist.size(); ++b) {
      const double h = hist[b] / kept;
      if (target[b] <= 0.0) {
        EXPECT_EQ(hist[b], 0.0) << "a direction kept where the target is zero";
        continue;
      }
      d += ((h - target[b]) * (h - target[b]) - h * (1.0 - h) / kept) / target[b];
    }
    return d;
  };
  const double d1 = divergence(1, 40000), d4 = divergence(4, 40000), d32 = divergence(32, 20000);
  std::printf("RIS divergence from the target: M=1 %.4f, M=4 %.4f, M=32 %.4f\n", d1, d4, d32);
  EXPECT_GT(d1, 0.05);
  EXPECT_LT(d4, 0.4 * d1);
  EXPECT_LT(d32, 0.4 * d4);
}

// An all-black map or a black material: exactly zero, never NaN.
TEST(Competitors, BlackIsZero) {
  ShadingSetup black = makeSetup("black", constantEnvironment(2, glm::vec3(0.0f)), ggx(0.3f, glm::vec3(0.5f)),
                                 {0.0f, 1.0f, 0.3f});
  Material none = lambert(0.0f);
  ShadingSetup dark = makeSetup("black-material", sunrise(), none, {0.0f, 1.0f, 0.3f});
  for (Method m : {Method::Ris, Method::Tsis, Method::Wis, Method::WisBiased}) {
    EXPECT_EQ(repeatedEstimates(black, m, 50, 4, 1).mean, glm::dvec3(0.0)) << methodName(m);
    EXPECT_EQ(repeatedEstimates(dark, m, 50, 4, 1).mean, glm::dvec3(0.0)) << methodName(m);
  }
}
