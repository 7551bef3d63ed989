#include "healpix.h"

#include <chealpix.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "chi2.h"

namespace hp = ht::healpix;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kChealpixOrders[] = {0, 1, 3, 8, 13};

int64_t nsideOf(int order) { return int64_t(1) << order; }

double angle(const glm::dvec3& a, const glm::dvec3& b) {
  return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b));
}

glm::dvec3 fromZPhi(double z, double phi) {
  const double s = std::sqrt((1.0 - z) * (1.0 + z));
  return {s * std::cos(phi), s * std::sin(phi), z};
}

struct SphereSampler {
  std::mt19937_64 rng;
  std::uniform_real_distribution<double> zDist{-1.0, 1.0};
  std::uniform_real_distribution<double> phiDist{0.0, 2.0 * kPi};
  explicit SphereSampler(uint64_t seed) : rng(seed) {}
  void zphi(double& z, double& phi) {
    z = zDist(rng);
    phi = phiDist(rng);
  }
  glm::dvec3 dir() {
    double z, phi;
    zphi(z, phi);
    return fromZPhi(z, phi);
  }
};

uint64_t randomPixel(std::mt19937_64& rng, int order) {
  return std::uniform_int_distribution<uint64_t>(0, hp::pixelCount(order) - 1)(rng);
}

// Area element of the face projection, by central differences.
double faceJacobian(int face, double x, double y, double h) {
  const glm::dvec3 dx = hp::faceXYToVec(face, x + h, y) - hp::faceXYToVec(face, x - h, y);
  const glm::dvec3 dy = hp::faceXYToVec(face, x, y + h) - hp::faceXYToVec(face, x, y - h);
  return glm::length(glm::cross(dx, dy)) / (4.0 * h * h);
}

}  // namespace

TEST(Healpix, ZPhiToPixMatchesChealpix) {
  SphereSampler sampler(0x5eed0001);
  std::uniform_real_distribution<double> poleTheta(0.0, 0.02);
  constexpr int kSamples = 150000;
  for (int order : kChealpixOrders) {
    int mismatches = 0;
    for (int i = 0; i < kSamples; ++i) {
      double z, phi;
      sampler.zphi(z, phi);
      double theta = std::acos(z);
      if (i % 10 == 0) theta = poleTheta(sampler.rng);  // chealpix's sin(theta) branch
      if (i % 10 == 1) theta = kPi - poleTheta(sampler.rng);
      if (i % 7 == 0) phi += 2.0 * kPi * double(int(i % 5) - 2);  // wrapping
      int64_t ref;
      ang2pix_nest64(nsideOf(order), theta, phi, &ref);
      const uint64_t got = hp::zphiToPix(order, std::cos(theta), phi);
      if (got != uint64_t(ref) && ++mismatches <= 5)
        ADD_FAILURE() << "order " << order << " theta " << theta << " phi " << phi << ": got "
                      << got << " chealpix " << ref;
    }
    EXPECT_EQ(mismatches, 0) << "order " << order;
  }
}

TEST(Healpix, VecToPixMatchesChealpix) {
  SphereSampler sampler(0x5eed0002);
  std::uniform_real_distribution<double> scale(0.01, 100.0);
  std::uniform_real_distribution<double> small(-0.05, 0.05);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int order : kChealpixOrders) {
    int mismatches = 0;
    auto check = [&](const glm::dvec3& v) {
      const double vec[3] = {v.x, v.y, v.z};
      int64_t ref;
      vec2pix_nest64(nsideOf(order), vec, &ref);
      const uint64_t got = hp::vecToPix(order, v);
      if (got != uint64_t(ref) && ++mismatches <= 5)
        ADD_FAILURE() << "order " << order << " v (" << v.x << ", " << v.y << ", " << v.z
                      << "): got " << got << " chealpix " << ref;
    };
    for (int i = 0; i < 100000; ++i) check(sampler.dir() * scale(sampler.rng));
    // Near the poles chealpix switches to sin(theta) from x, y.
    for (int i = 0; i < 20000; ++i)
      check({small(sampler.rng), small(sampler.rng), i % 2 ? 1.0 : -1.0});
    // Points on pixel edges and corners (at this and finer orders) stress
    // the truncations.
    for (int i = 0; i < 20000; ++i) {
      const int o = std::min(hp::kMaxOrder, order + i % 3);
      const uint64_t p = randomPixel(sampler.rng, o);
      const double dx = i % 4 == 0 ? unit(sampler.rng) : double((i / 4) % 3) * 0.5;
      const double dy = double((i / 12) % 3) * 0.5;
      check(hp::pixToVec(o, p, dx, dy));
    }
    // Edges and corners of pixels close to the poles, where 1 - |z| alone
    // would not resolve the boundary.
    const uint32_t last = uint32_t(nsideOf(order) - 1);
    for (int i = 0; i < 4000; ++i) {
      const bool north = i % 8 < 4;
      const uint32_t u = uint32_t(i / 8 % 32) & last, w = uint32_t(i / 256 % 16) & last;
      const uint64_t p = north ? hp::xyfToPix(order, last - u, last - w, i % 4)
                               : hp::xyfToPix(order, u, w, i % 4 + 8);
      check(hp::pixToVec(order, p, double(i % 3) * 0.5, double(i / 3 % 3) * 0.5));
    }
    EXPECT_EQ(mismatches, 0) << "order " << order;
  }
}

TEST(Healpix, PixelCentresMatchChealpix) {
  std::mt19937_64 rng(0x5eed0003);
  auto check = [](int order, uint64_t p) {
    double theta, phi;
    pix2ang_nest64(nsideOf(order), int64_t(p), &theta, &phi);
    const glm::dvec3 v = hp::pixToVec(order, p);
    double z, myPhi;
    hp::pixToZPhi(order, p, 0.5, 0.5, z, myPhi);
    EXPECT_NEAR(std::atan2(std::sqrt(v.x * v.x + v.y * v.y), v.z), theta, 1e-12)
        << "order " << order << " pix " << p;
    EXPECT_NEAR(myPhi, phi, 1e-12) << "order " << order << " pix " << p;
    EXPECT_NEAR(glm::length(v), 1.0, 1e-15);
    EXPECT_NEAR(z, v.z, 1e-15);
    EXPECT_NEAR(std::atan2(v.y, v.x), std::remainder(phi, 2.0 * kPi), 1e-11);
  };
  for (int order = 0; order <= 3; ++order)
    for (uint64_t p = 0; p < hp::pixelCount(order); ++p) check(order, p);
  for (int order : {8, 13})
    for (int i = 0; i < 20000; ++i) check(order, randomPixel(rng, order));
  // Pixels touching the poles, where precision is hardest.
  const uint32_t last = uint32_t(nsideOf(13) - 1);
  for (int f = 0; f < 4; ++f) {
    check(13, hp::xyfToPix(13, last, last, f));
    check(13, hp::xyfToPix(13, 0, 0, f + 8));
  }
}

TEST(Healpix, RingIndexMatchesChealpix) {
  std::mt19937_64 rng(0x5eed0009);
  for (int order : kChealpixOrders) {
    const int64_t nside = nsideOf(order), rings = 4 * nside - 1;
    std::vector<int64_t> start(size_t(rings) + 2, 0);
    for (int64_t r = 1; r <= rings; ++r) start[size_t(r) + 1] = start[size_t(r)] + hp::ringPixelCount(order, r);
    ASSERT_EQ(uint64_t(start[size_t(rings) + 1]), hp::pixelCount(order)) << "order " << order;
    const uint64_t count = hp::pixelCount(order);
    const uint64_t samples = std::min<uint64_t>(count, 200000);
    int mismatches = 0;
    for (uint64_t i = 0; i < samples; ++i) {
      const uint64_t pix = samples == count ? i : rng() % count;
      uint32_t ix, iy;
      int face;
      hp::pixToXYF(order, pix, ix, iy, face);
      int64_t ring, pos, ref;
      hp::xyfToRing(order, ix, iy, face, ring, pos);
      nest2ring64(nside, int64_t(pix), &ref);
      const bool ok = ring >= 1 && ring <= rings && pos >= 0 && pos < hp::ringPixelCount(order, ring) &&
                      start[size_t(ring)] + pos == ref;
      if (!ok && ++mismatches <= 5)
        ADD_FAILURE() << "order " << order << " pixel " << pix << ": ring " << ring << " pos " << pos
                      << ", chealpix ring index " << ref;
    }
    EXPECT_EQ(mismatches, 0) << "order " << order;
  }
}

TEST(Healpix, XYFRoundTrip) {
  std::mt19937_64 rng(0x5eed0004);
  for (int order = 0; order <= hp::kMaxOrder; ++order) {
    const uint32_t nside = uint32_t(nsideOf(order));
    std::uniform_int_distribution<uint32_t> coord(0, nside - 1);
    for (int i = 0; i < 2000; ++i) {
      const uint32_t ix = coord(rng), iy = coord(rng);
      const int face = i % 12;
      const uint64_t p = hp::xyfToPix(order, ix, iy, face);
      ASSERT_LT(p, hp::pixelCount(order));
      EXPECT_EQ(p >> (2 * order), uint64_t(face));
      uint32_t ix2, iy2;
      int face2;
      hp::pixToXYF(order, p, ix2, iy2, face2);
      EXPECT_EQ(ix2, ix);
      EXPECT_EQ(iy2, iy);
      EXPECT_EQ(face2, face);
    }
  }
  // Nested layout: ix on the even bits, iy on the odd bits.
  EXPECT_EQ(hp::xyfToPix(2, 1, 0, 0), 1u);
  EXPECT_EQ(hp::xyfToPix(2, 0, 1, 0), 2u);
  EXPECT_EQ(hp::xyfToPix(2, 3, 2, 5), 5u * 16u + 13u);
  EXPECT_EQ(hp::xyfToPix(13, 8191, 8191, 11), hp::pixelCount(13) - 1);
}

TEST(Healpix, PointInPixelRoundTrip) {
  std::mt19937_64 rng(0x5eed0005);
  std::uniform_real_distribution<double> frac(0.01, 0.99);
  for (int order = 0; order <= hp::kMaxOrder; ++order) {
    for (int i = 0; i < 5000; ++i) {
      const uint64_t p = randomPixel(rng, order);
      const double dx = frac(rng), dy = frac(rng);
      const glm::dvec3 v = hp::pixToVec(order, p, dx, dy);
      ASSERT_EQ(hp::vecToPix(order, v), p) << "order " << order << " dx " << dx << " dy " << dy;
      double z, phi;
      hp::pixToZPhi(order, p, dx, dy, z, phi);
      ASSERT_EQ(hp::zphiToPix(order, z, phi), p) << "order " << order;
      EXPECT_NEAR(z, v.z, 1e-15);
    }
  }
}

TEST(Healpix, ChildrenNestInsideParent) {
  std::mt19937_64 rng(0x5eed0006);
  std::uniform_real_distribution<double> frac(0.01, 0.99);
  for (int order = 0; order < hp::kMaxOrder; ++order) {
    for (int i = 0; i < 500; ++i) {
      const uint64_t p = randomPixel(rng, order);
      uint32_t ix, iy;
      int face;
      hp::pixToXYF(order, p, ix, iy, face);
      for (uint64_t c = 4 * p; c < 4 * p + 4; ++c) {
        ASSERT_EQ(c >> 2, p);
        uint32_t cx, cy;
        int cf;
        hp::pixToXYF(order + 1, c, cx, cy, cf);
        EXPECT_EQ(cf, face);
        EXPECT_EQ(cx, 2 * ix + uint32_t(c & 1));
        EXPECT_EQ(cy, 2 * iy + uint32_t((c >> 1) & 1));
        const glm::dvec3 v = hp::pixToVec(order + 1, c, frac(rng), frac(rng));
        ASSERT_EQ(hp::vecToPix(order + 1, v), c);
        ASSERT_EQ(hp::vecToPix(order, v), p) << "order " << order << " child " << c;
      }
    }
  }
}

TEST(Healpix, UniformPointsInPixelPassChi2) {
  struct Case {
    const char* name;
    int order;
    uint64_t pix;
  };
  const Case cases[] = {
      {"polar cap, touching the north pole", 4, hp::xyfToPix(4, 15, 15, 1)},
      {"polar cap, south", 5, hp::xyfToPix(5, 3, 5, 10)},
      {"equatorial", 4, hp::xyfToPix(4, 7, 8, 5)},
      {"straddling z = 2/3", 4, hp::xyfToPix(4, 8, 7, 2)},
      {"face corner on the equator", 3, hp::xyfToPix(3, 0, 0, 3)},
      {"base face, order 0", 0, 0},
      {"base face, order 0, equatorial", 0, 6},
      {"order 1", 1, 4 * 9 + 2},
  };
  constexpr int kCases = int(std::size(cases)) + 1;  // + the whole-sphere test below
  const double alpha = ht::test::sidakAlpha(0.01, kCases);
  constexpr int kPoints = 200000;
  constexpr int kDepth = 3;
  std::mt19937_64 rng(0x5eed0007);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (const Case& c : cases) {
    std::vector<double> observed(64, 0.0);
    const std::vector<double> expected(64, kPoints / 64.0);
    for (int i = 0; i < kPoints; ++i) {
      const glm::dvec3 v = hp::pixToVec(c.order, c.pix, unit(rng), unit(rng));
      const uint64_t sub = hp::vecToPix(c.order + kDepth, v);
      ASSERT_EQ(sub >> (2 * kDepth), c.pix) << c.name;
      observed[sub & 63] += 1.0;
    }
    const ht::test::Chi2Result r = ht::test::chi2Test(observed, expected);
    EXPECT_EQ(r.dof, 63);
    EXPECT_GT(r.pValue, alpha) << c.name << "\n" << ht::test::describe(r, observed, expected);
  }

  // Independent of the HEALPix grid: a uniform random pixel plus uniform
  // (dx, dy) must be uniform on the sphere, binned in equal-area z x phi
  // cells (Archimedes: equal z-slabs have equal area).
  constexpr int kZBins = 16, kPhiBins = 12;
  std::vector<double> observed(kZBins * kPhiBins, 0.0);
  const std::vector<double> expected(observed.size(), double(kPoints) / observed.size());
  for (int i = 0; i < kPoints; ++i) {
    double z, phi;
    hp::pixToZPhi(2, randomPixel(rng, 2), unit(rng), unit(rng), z, phi);
    const int zi = std::min(kZBins - 1, int((z + 1.0) * 0.5 * kZBins));
    const int pi = std::min(kPhiBins - 1, int(phi / (2.0 * kPi) * kPhiBins));
    ASSERT_GE(pi, 0);
    observed[zi * kPhiBins + pi] += 1.0;
  }
  const ht::test::Chi2Result r = ht::test::chi2Test(observed, expected);
  EXPECT_GT(r.pValue, alpha) << "whole sphere\n" << ht::test::describe(r, observed, expected);
}

TEST(Healpix, ProjectionIsEqualArea) {
  // |d v / dx x d v / dy| over a face is 4 pi / 12 everywhere.
  std::mt19937_64 rng(0x5eed0008);
  std::uniform_real_distribution<double> unit(0.001, 0.999);
  const double faceArea = 4.0 * kPi / 12.0;
  for (int i = 0; i < 20000; ++i) {
    const int face = i % 12;
    const double x = unit(rng), y = unit(rng);
    const double jr = (face < 4 ? 2.0 : face < 8 ? 3.0 : 4.0) - x - y;
    if (std::fabs(jr - 1.0) < 1e-4 || std::fabs(jr - 3.0) < 1e-4) continue;  // kink at |z| = 2/3
    EXPECT_NEAR(faceJacobian(face, x, y, 1e-5), faceArea, 1e-6 * faceArea)
        << "face " << face << " x " << x << " y " << y;
  }
}

TEST(Healpix, PixelAreasSumToSphere) {
  // Per-pixel areas from the projection's numerical Jacobian (midpoint rule
  // in (dx, dy)): each is 4 pi / Npix and together they cover the sphere.
  for (int order = 0; order <= 2; ++order) {
    const double fn = double(nsideOf(order));
    constexpr int kGrid = 16;
    double total = 0.0;
    for (uint64_t p = 0; p < hp::pixelCount(order); ++p) {
      uint32_t ix, iy;
      int face;
      hp::pixToXYF(order, p, ix, iy, face);
      double area = 0.0;
      for (int j = 0; j < kGrid; ++j)
        for (int i = 0; i < kGrid; ++i)
          area += faceJacobian(face, (ix + (i + 0.5) / kGrid) / fn, (iy + (j + 0.5) / kGrid) / fn,
                               1e-6) /
                  (fn * fn * kGrid * kGrid);
      EXPECT_NEAR(area, hp::pixelSolidAngle(order), 1e-6 * hp::pixelSolidAngle(order))
          << "order " << order << " pix " << p;
      total += area;
    }
    EXPECT_NEAR(total, 4.0 * kPi, 1e-6);
    EXPECT_NEAR(hp::pixelSolidAngle(order) * double(hp::pixelCount(order)), 4.0 * kPi, 1e-12);
  }
  EXPECT_EQ(hp::pixelCount(13), 12ull << 26);
}

TEST(Healpix, BoundingConeIsConservative) {
  std::mt19937_64 rng(0x5eed0009);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto check = [&](int order, uint64_t p, int points) {
    const hp::Cone cone = hp::boundingCone(order, p);
    ASSERT_NEAR(glm::length(cone.axis), 1.0, 1e-14);
    ASSERT_LT(angle(cone.axis, hp::pixToVec(order, p)), 1e-14);
    double maxCorner = 0.0;
    for (int c = 0; c < 4; ++c)
      maxCorner = std::max(maxCorner, angle(cone.axis, hp::pixToVec(order, p, c & 1, c >> 1)));
    EXPECT_LE(cone.radius, 1.5 * maxCorner) << "order " << order << " pix " << p;
    EXPECT_LT(cone.radius, kPi);
    double maxSeen = 0.0;
    for (int i = 0; i < points; ++i) {
      double dx = unit(rng), dy = unit(rng);
      if (i % 4 == 1) dx = double(i / 4 % 2);  // on the edges
      if (i % 4 == 2) dy = double(i / 4 % 2);
      maxSeen = std::max(maxSeen, angle(cone.axis, hp::pixToVec(order, p, dx, dy)));
    }
    EXPECT_LE(maxSeen, cone.radius) << "order " << order << " pix " << p;
  };
  for (int order = 0; order <= 2; ++order)
    for (uint64_t p = 0; p < hp::pixelCount(order); ++p) check(order, p, 2000);
  for (int order = 3; order <= hp::kMaxOrder; ++order) {
    for (int i = 0; i < 30; ++i) check(order, randomPixel(rng, order), 2000);
    const uint32_t last = uint32_t(nsideOf(order) - 1);
    const uint32_t mid = last / 2;
    check(order, hp::xyfToPix(order, last, last, 0), 4000);  // north pole
    check(order, hp::xyfToPix(order, 0, 0, 9), 4000);        // south pole
    check(order, hp::xyfToPix(order, 0, 0, 1), 4000);        // face corner on equator
    check(order, hp::xyfToPix(order, mid + 1, mid, 3), 4000);  // straddles z = 2/3
    check(order, hp::xyfToPix(order, last, 0, 4), 4000);     // equatorial face corner
  }
}

TEST(Chi2Helper, GammaQMatchesReferenceValues) {
  using ht::test::chi2PValue;
  // References from mpmath (30 digits).
  EXPECT_NEAR(chi2PValue(18.307038053275146, 10), 0.05, 1e-12);
  EXPECT_NEAR(chi2PValue(3.841458820694124, 1), 0.05, 1e-12);
  EXPECT_NEAR(chi2PValue(0.1, 3), 0.991837423731876478, 1e-12);
  EXPECT_NEAR(chi2PValue(40.0, 7), 1.25879038737130878e-6, 1e-15);
  EXPECT_NEAR(chi2PValue(1000.0, 1000), 0.494052853829239642, 1e-10);
  EXPECT_NEAR(chi2PValue(1100.0, 1000), 0.0146144081262951940, 1e-11);
  EXPECT_NEAR(chi2PValue(300.0, 200) / 5.92454033548391583e-6, 1.0, 1e-9);
  EXPECT_NEAR(chi2PValue(51000.0, 50000), 8.34579193121917181e-4, 1e-9);
  for (double x : {0.01, 0.5, 2.0, 7.0, 30.0})
    EXPECT_NEAR(ht::test::gammaQ(1.0, x), std::exp(-x), 1e-14 * std::exp(-x) + 1e-16);
  EXPECT_EQ(chi2PValue(5.0, 0), 1.0);
  EXPECT_NEAR(ht::test::sidakAlpha(0.01, 1), 0.01, 1e-15);
  EXPECT_NEAR(ht::test::sidakAlpha(0.05, 10), 1.0 - std::pow(0.95, 0.1), 1e-15);
  EXPECT_LT(ht::test::sidakAlpha(0.05, 10), 0.05 / 10 * 1.03);
  EXPECT_GT(ht::test::sidakAlpha(0.05, 10), 0.05 / 10);
}

TEST(Chi2Helper, PoolsSmallBinsInOrder) {
  // Expected 2,2,2 | 10 | 1,1,1,1,1 | 3 -> cells {6}, {10}, {5}, remainder 3 into the last.
  const std::vector<double> expected = {2, 2, 2, 10, 1, 1, 1, 1, 1, 3};
  const std::vector<int> observed = {1, 3, 2, 12, 0, 2, 1, 1, 1, 4};
  const ht::test::Chi2Result r = ht::test::chi2Test(observed, expected);
  EXPECT_EQ(r.pooledCells, 3);
  EXPECT_EQ(r.dof, 2);
  const double stat = 0.0 / 6.0 + 4.0 / 10.0 + (9.0 - 8.0) * (9.0 - 8.0) / 8.0;
  EXPECT_NEAR(r.stat, stat, 1e-12);
  EXPECT_NEAR(r.pValue, std::exp(-stat / 2.0), 1e-12);  // dof 2: Q(1, x/2)

  const ht::test::Chi2Result impossible =
      ht::test::chi2Test(std::vector<int>{5, 1, 5}, std::vector<double>{5.5, 0.0, 5.5});
  EXPECT_EQ(impossible.pValue, 0.0);
  EXPECT_NE(ht::test::worstBins(std::vector<int>{5, 1, 5}, std::vector<double>{5.5, 0.0, 5.5}, 1)
                .find("bin 1:"),
            std::string::npos);
}

TEST(Chi2Helper, DetectsBiasAndAcceptsUniform) {
  std::mt19937_64 rng(0x5eed000a);
  constexpr int kBins = 50, kSamples = 50000;
  std::uniform_int_distribution<int> bin(0, kBins - 1);
  std::vector<double> fair(kBins, 0.0), biased(kBins, 0.0);
  for (int i = 0; i < kSamples; ++i) {
    fair[bin(rng)] += 1.0;
    const int b = bin(rng);
    biased[(b == 0 && i % 5 == 0) ? 1 : b] += 1.0;  // moves 20% of bin 0 into bin 1
  }
  const std::vector<double> expected(kBins, double(kSamples) / kBins);
  EXPECT_GT(ht::test::chi2Test(fair, expected).pValue, 1e-3);
  EXPECT_LT(ht::test::chi2Test(biased, expected).pValue, 1e-6);
}

TEST(Chi2Helper, ExpectedCountsIntegratePdfOverPixels) {
  const double n = 1e6;
  const std::vector<double> uniform =
      ht::test::expectedCountsHealpix(2, 4, [](glm::dvec3) { return 1.0 / (4.0 * kPi); }, n);
  ASSERT_EQ(uniform.size(), hp::pixelCount(2));
  for (double e : uniform) EXPECT_NEAR(e, n / 192.0, 1e-9 * n);

  // pdf (1 + z) / (4 pi). Per north base face, the integral of z is
  // 23 pi / 108: the cap z > 2/3 (5 pi / 9 over four faces) plus the
  // band 0 < z < 2/3, where the north faces hold a fraction 3z/2 of each
  // ring (8 pi / 27 over four faces). Equatorial faces are symmetric in z.
  auto pdf = [](glm::dvec3 d) { return (1.0 + d.z) / (4.0 * kPi); };
  const std::vector<double> faces = ht::test::expectedCountsHealpix(0, 64, pdf, n);
  EXPECT_NEAR(faces[0], n * 59.0 / 432.0, 1e-5 * n);
  EXPECT_NEAR(faces[4], n / 12.0, 1e-9 * n);
  EXPECT_NEAR(faces[8], n * 13.0 / 432.0, 1e-5 * n);
  double total = 0.0;
  for (double x : ht::test::expectedCountsHealpix(1, 8, pdf, n)) total += x;
  EXPECT_NEAR(total, n, 1e-4 * n);
  EXPECT_EQ(ht::test::binIndex(3, hp::pixToVec(3, 77, 0.3, 0.6)), 77u);
}
