// Chi-square goodness-of-fit helpers for sampler tests.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <gtest/gtest.h>

#include "healpix.h"
#include "rng.h"

namespace ht::test {

struct Chi2Result {
  double stat = 0.0;
  int dof = 0;
  double pValue = 1.0;
  int pooledCells = 0;  // cells after pooling low-expectation bins
};

// Per-test significance that keeps the family-wise error rate at alpha
// over `tests` independent tests.
inline double sidakAlpha(double alpha, int tests) {
  return 1.0 - std::pow(1.0 - alpha, 1.0 / tests);
}

namespace detail {

// Lower regularized gamma P(a, x) by its power series; converges fast for
// x < a + 1.
inline double gammaPSeries(double a, double x) {
  double term = 1.0 / a;
  double sum = term;
  for (int n = 1; n < 1000000; ++n) {
    term *= x / (a + n);
    sum += term;
    if (std::fabs(term) < std::fabs(sum) * 1e-16) break;
  }
  return sum * std::exp(-x + a * std::log(x) - std::lgamma(a));
}

// Upper regularized gamma Q(a, x) by its continued fraction (modified
// Lentz); converges fast for x >= a + 1.
inline double gammaQContinuedFraction(double a, double x) {
  constexpr double kTiny = 1e-300;
  double b = x + 1.0 - a;
  double c = 1.0 / kTiny;
  double d = 1.0 / b;
  double h = d;
  for (int i = 1; i < 1000000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::fabs(d) < kTiny) d = kTiny;
    c = b + an / c;
    if (std::fabs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::fabs(delta - 1.0) < 1e-16) break;
  }
  return std::exp(-x + a * std::log(x) - std::lgamma(a)) * h;
}

}  // namespace detail

// Upper regularized incomplete gamma function Q(a, x) = Gamma(a, x) / Gamma(a).
inline double gammaQ(double a, double x) {
  if (x <= 0.0) return 1.0;
  if (x < a + 1.0) return std::max(0.0, 1.0 - detail::gammaPSeries(a, x));
  return detail::gammaQContinuedFraction(a, x);
}

// Survival function of the chi-square distribution.
inline double chi2PValue(double stat, int dof) {
  if (dof <= 0) return 1.0;
  return gammaQ(0.5 * dof, 0.5 * stat);
}

// Pearson test. Bins with expected < 5 are merged, in order, into pooled
// cells until each reaches expected >= 5; a remainder that never gets there
// joins the last cell. Counts observed where nothing is expected make the
// test fail outright (stat = inf, p = 0) since pooling would hide them.
template <class Observed>
Chi2Result chi2Test(const Observed& observed, const std::vector<double>& expected) {
  constexpr double kMinExpected = 5.0;
  Chi2Result r;
  const size_t n = expected.size();
  for (size_t i = 0; i < n; ++i) {
    if (expected[i] <= 0.0 && double(observed[i]) > 0.0) {
      r.stat = std::numeric_limits<double>::infinity();
      r.pValue = 0.0;
      return r;
    }
  }
  std::vector<double> cellObs, cellExp;
  double poolObs = 0.0, poolExp = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const double o = double(observed[i]);
    const double e = expected[i];
    if (e >= kMinExpected) {
      cellObs.push_back(o);
      cellExp.push_back(e);
      continue;
    }
    poolObs += o;
    poolExp += e;
    if (poolExp >= kMinExpected) {
      cellObs.push_back(poolObs);
      cellExp.push_back(poolExp);
      poolObs = poolExp = 0.0;
    }
  }
  if (poolExp > 0.0 || poolObs > 0.0) {
    if (cellExp.empty()) {
      cellObs.push_back(poolObs);
      cellExp.push_back(poolExp);
    } else {
      cellObs.back() += poolObs;
      cellExp.back() += poolExp;
    }
  }
  r.pooledCells = int(cellExp.size());
  for (size_t i = 0; i < cellExp.size(); ++i) {
    if (cellExp[i] <= 0.0) continue;
    const double diff = cellObs[i] - cellExp[i];
    r.stat += diff * diff / cellExp[i];
  }
  r.dof = std::max(0, r.pooledCells - 1);
  r.pValue = chi2PValue(r.stat, r.dof);
  return r;
}

// The `count` bins with the largest Pearson residuals, one per line, for a
// failure message.
template <class Observed>
std::string worstBins(const Observed& observed, const std::vector<double>& expected,
                      int count = 10) {
  const size_t n = expected.size();
  auto residual = [&](size_t i) {
    const double diff = double(observed[i]) - expected[i];
    if (expected[i] <= 0.0) return diff != 0.0 ? std::numeric_limits<double>::infinity() : 0.0;
    return std::fabs(diff) / std::sqrt(expected[i]);
  };
  std::vector<size_t> order(n);
  std::iota(order.begin(), order.end(), size_t(0));
  const size_t shown = std::min(n, size_t(std::max(count, 0)));
  std::partial_sort(order.begin(), order.begin() + shown, order.end(),
                    [&](size_t a, size_t b) { return residual(a) > residual(b); });
  std::string s;
  char line[160];
  for (size_t k = 0; k < shown; ++k) {
    const size_t i = order[k];
    std::snprintf(line, sizeof line, "  bin %zu: observed %.0f, expected %.2f (residual %.2f)\n", i,
                  double(observed[i]), expected[i], residual(i));
    s += line;
  }
  return s;
}

template <class Observed>
std::string describe(const Chi2Result& r, const Observed& observed,
                     const std::vector<double>& expected, int count = 10) {
  char head[160];
  std::snprintf(head, sizeof head, "chi2 = %.3f, dof = %d, p = %.3g, cells = %d\n", r.stat, r.dof,
                r.pValue, r.pooledCells);
  return head + worstBins(observed, expected, count);
}

// Equal-area bins: the nested HEALPix pixels at binOrder.
inline uint64_t binIndex(int binOrder, const glm::dvec3& dir) {
  return healpix::vecToPix(binOrder, dir);
}

// Expected sample counts per HEALPix bin for a solid-angle density `pdf`,
// integrated with a subdiv x subdiv midpoint rule in face coordinates,
// which is exact in measure because the projection is equal-area.
inline std::vector<double> expectedCountsHealpix(int binOrder, int subdiv,
                                                 std::function<double(glm::dvec3)> pdf,
                                                 double sampleCount) {
  const uint64_t bins = healpix::pixelCount(binOrder);
  const double weight =
      sampleCount * healpix::pixelSolidAngle(binOrder) / (double(subdiv) * subdiv);
  std::vector<double> expected(bins);
  for (uint64_t p = 0; p < bins; ++p) {
    double sum = 0.0;
    for (int j = 0; j < subdiv; ++j)
      for (int i = 0; i < subdiv; ++i)
        sum += pdf(healpix::pixToVec(binOrder, p, (i + 0.5) / subdiv, (j + 0.5) / subdiv));
    expected[p] = weight * sum;
  }
  return expected;
}

// One sampler's test against its own density, in the spirit of Mitsuba 3's
// ChiSquareTest: a sample function, its density and the domain's bins (the
// equal-area HEALPix pixels at binOrder, in the frame the sample function
// returns its directions in).
struct DensityCase {
  std::string name;
  std::function<glm::dvec3(Rng&)> sample;  // one direction per call
  std::function<double(glm::dvec3)> pdf;   // solid-angle density; unused where `expected` is given
  int binOrder = 4;
  int subdiv = 12;       // the midpoint rule per bin for the expected counts
  int samples = 1'000'000;
  std::vector<double> expected = {};  // the expected counts, where the density gives them exactly
};

// Every case: its samples from Rng(seed, stream), binned, against the
// expected counts by Pearson's test at a Sidak-corrected level (family-wise
// alpha 0.01 over the cases, or over `family` tests where the cases are
// run a few at a time); each sample must be a finite direction and the
// density must integrate to one.
inline void expectDensitiesMatch(const std::vector<DensityCase>& cases, uint32_t seed, uint32_t stream,
                                 int family = 0) {
  const double level = sidakAlpha(0.01, family > 0 ? family : int(cases.size()));
  for (const DensityCase& c : cases) {
    const std::vector<double> expected =
        c.expected.empty() ? expectedCountsHealpix(c.binOrder, c.subdiv, c.pdf, c.samples) : c.expected;
    ASSERT_EQ(expected.size(), healpix::pixelCount(c.binOrder)) << c.name;
    std::vector<uint64_t> observed(expected.size(), 0);
    Rng rng(seed, stream);
    for (int i = 0; i < c.samples; ++i) {
      const glm::dvec3 d = c.sample(rng);
      ASSERT_TRUE(std::isfinite(d.x) && std::isfinite(d.y) && std::isfinite(d.z) && glm::length(d) > 0.5)
          << c.name << ": sample " << i << " is not a direction";
      ++observed[binIndex(c.binOrder, d)];
    }
    double mass = 0.0;
    for (double e : expected) mass += e;
    EXPECT_NEAR(mass / c.samples, 1.0, 2e-3) << c.name << ": the density does not integrate to one";
    const Chi2Result r = chi2Test(observed, expected);
    EXPECT_GT(r.pValue, level) << c.name << ": " << describe(r, observed, expected);
  }
}

}  // namespace ht::test
