// The HEALPix resample of equirectangular maps against integrals taken
// directly over the input texels: the renderer's L(w) must carry the same
// power as the texel-constant input, and the same irradiance up to the
// cosine's variation inside a HEALPix pixel.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "environment.h"
#include "estimator_harness.h"
#include "healpix.h"
#include "image_io.h"

using namespace ht;

namespace {

constexpr double kPiD = 3.14159265358979323846;

// Integrals of the equirectangular map taken as constant over each texel:
// row y spans z = cos(theta) in [cos((y+1) pi/H), cos(y pi/H)], each texel
// 2 pi / W of azimuth, so its solid angle is 2 pi / W (z0 - z1) and its
// integral of cos+ about +y is 2 pi / W (max(z0,0)^2 - max(z1,0)^2) / 2.
struct TexelIntegrals {
  glm::dvec3 power{0.0};       // integral of L
  glm::dvec3 irradiance{0.0};  // integral of L cos+(+y, w)
  glm::dvec3 cosineSpread{0.0};  // sum of pixel energy x (max - min of cos+ over the pixel)
};

TexelIntegrals texelIntegrals(const ImageRGB& img) {
  TexelIntegrals r;
  const double dphi = 2.0 * kPiD / img.width;
  for (int y = 0; y < img.height; ++y) {
    const double z0 = std::cos(kPiD * y / img.height), z1 = std::cos(kPiD * (y + 1) / img.height);
    const double p0 = std::max(z0, 0.0), p1 = std::max(z1, 0.0);
    glm::dvec3 row(0.0);
    for (int x = 0; x < img.width; ++x) row += glm::dvec3(img.at(x, y));
    r.power += row * (dphi * (z0 - z1));
    r.irradiance += row * (dphi * 0.5 * (p0 * p0 - p1 * p1));
  }
  return r;
}

// The same integrals of the renderer's piecewise-constant HEALPix map. The
// HEALPix z (world +y) of a point depends only on x + y in its base face's
// coordinates, so the integral of cos+ over a pixel depends only on the
// face's row (north, equator, south) and ix + iy: one fine grid per class.
TexelIntegrals healpixIntegrals(const Environment& env) {
  const int order = env.order;
  const uint32_t n = uint32_t(env.nside());
  const double omega = healpix::pixelSolidAngle(order);
  constexpr int kGrid = 64;
  std::vector<double> cosIntegral(3 * (2 * n - 1)), cosSpread(3 * (2 * n - 1));
  for (int row = 0; row < 3; ++row)
    for (uint32_t s = 0; s < 2 * n - 1; ++s) {
      const uint32_t ix = std::min(s, n - 1), iy = s - ix;
      const uint64_t pix = healpix::xyfToPix(order, ix, iy, 4 * row);
      double sum = 0.0, lo = 1.0, hi = 0.0;
      for (int j = 0; j <= kGrid; ++j)
        for (int i = 0; i <= kGrid; ++i) {
          double z, phi;
          healpix::pixToZPhi(order, pix, (i + 0.5) / kGrid, (j + 0.5) / kGrid, z, phi);
          if (i < kGrid && j < kGrid) sum += std::max(z, 0.0);
          healpix::pixToZPhi(order, pix, double(i) / kGrid, double(j) / kGrid, z, phi);
          lo = std::min(lo, std::max(z, 0.0));
          hi = std::max(hi, std::max(z, 0.0));
        }
      cosIntegral[row * (2 * n - 1) + s] = sum * omega / (kGrid * kGrid);
      cosSpread[row * (2 * n - 1) + s] = hi - lo;
    }
  TexelIntegrals r;
  for (uint64_t p = 0; p < env.radiance.size(); ++p) {
    uint32_t ix, iy;
    int face;
    healpix::pixToXYF(order, p, ix, iy, face);
    const glm::dvec3 l(env.radiance[p]);
    r.power += l * omega;
    r.irradiance += l * cosIntegral[(face / 4) * (2 * n - 1) + ix + iy];
    r.cosineSpread += l * omega * cosSpread[(face / 4) * (2 * n - 1) + ix + iy];
  }
  return r;
}

// A dim sky with one bright texel in the direction of the tests' sun.
ImageRGB onePixelSunImage(int width, int height) {
  ImageRGB img;
  img.width = width;
  img.height = height;
  img.pixels.assign(size_t(width) * height, glm::vec3(0.02f));
  double u, v;
  equirectUV(test::kSunDir, u, v);
  img.at(int(u * width), int(v * height)) = glm::vec3(50000.0f, 45000.0f, 37500.0f);
  return img;
}

ImageRGB sunriseImage() {
  ImageRGB img = readExr(std::string(HT_TEST_DATA) + "/env/sunrise.exr");
  sanitizeEnvironmentImage(img, "sunrise.exr");
  return img;
}

double maxRelativeError(const glm::dvec3& test, const glm::dvec3& ref) {
  double e = 0.0;
  for (int c = 0; c < 3; ++c) e = std::max(e, std::abs(test[c] - ref[c]) / std::abs(ref[c]));
  return e;
}

}  // namespace

// Irradiance on an up-facing Lambert plane (albedo 1, nothing in the way),
// L_o = E / pi, from the HEALPix map against the exact integral of the input
// texels, for a captured sky and for a sun smaller than a HEALPix pixel.
TEST(Environment, LambertIrradianceMatchesTheTexels) {
  const std::vector<std::pair<std::string, ImageRGB>> maps = {{"sunrise", sunriseImage()},
                                                              {"one-pixel-sun", onePixelSunImage(1024, 512)}};
  for (const auto& [name, img] : maps) {
    const TexelIntegrals exact = texelIntegrals(img);
    const glm::dvec3 ref = exact.irradiance / kPiD;
    std::printf("%-14s exact        L_o = %.6f %.6f %.6f\n", name.c_str(), ref.x, ref.y, ref.z);
    for (int order : {6, 8, 10}) {
      SCOPED_TRACE(name + " at Nside " + std::to_string(1 << order));
      const Environment env = environmentFromEquirect(img, order, 0.0f, 1.0f);
      const TexelIntegrals got = healpixIntegrals(env);
      const glm::dvec3 lo = got.irradiance / kPiD;
      std::printf("%-14s Nside %-6d L_o = %.6f %.6f %.6f (max rel. error %.2e, power %.2e)\n", name.c_str(),
                  1 << order, lo.x, lo.y, lo.z, maxRelativeError(lo, ref),
                  maxRelativeError(got.power, exact.power));
      EXPECT_LT(maxRelativeError(got.power, exact.power), 1e-6);
      if (order >= 8) {
        EXPECT_LT(maxRelativeError(lo, ref), 1e-3);
      } else {
        // A HEALPix pixel holds the texels' average, so its cosine weight is
        // the pixel's mean cosine: each pixel's energy may be off by its
        // cosine's spread over the pixel (0.7 % for sunrise's low sun at
        // Nside 64), and no more.
        EXPECT_LT(std::abs(lo.y - ref.y), got.cosineSpread.y / kPiD);
      }
    }
  }
}

// Each HEALPix pixel against a brute-force average of the texel-constant map
// over it (K x K area-uniform points), for a random map whose texels are
// larger than the pixels, about their size and smaller; and a constant map
// stays constant.
TEST(Environment, PixelsHoldTheTexelAverage) {
  std::mt19937 gen(7);
  std::uniform_real_distribution<float> value(0.0f, 1.0f);
  ImageRGB img;
  img.width = 48;
  img.height = 24;
  img.pixels.resize(size_t(img.width) * img.height);
  for (glm::vec3& p : img.pixels) p = glm::vec3(value(gen), value(gen), value(gen));
  constexpr int kGrid = 128;
  for (int order : {1, 3, 4}) {
    SCOPED_TRACE("Nside " + std::to_string(1 << order));
    const Environment env = environmentFromEquirect(img, order, 0.0f, 1.0f);
    double worst = 0.0;
    for (uint64_t p = 0; p < env.radiance.size(); ++p) {
      glm::dvec3 sum(0.0);
      for (int j = 0; j < kGrid; ++j)
        for (int i = 0; i < kGrid; ++i) {
          // HEALPix frame: z = world y = cos(theta); the map's azimuth is pi - phi.
          double z, phi;
          healpix::pixToZPhi(order, p, (i + 0.5) / kGrid, (j + 0.5) / kGrid, z, phi);
          double u = (kPiD - phi) / (2.0 * kPiD);
          u -= std::floor(u);
          const int x = std::min(int(u * img.width), img.width - 1);
          const int y = std::min(int(std::acos(std::clamp(z, -1.0, 1.0)) / kPiD * img.height), img.height - 1);
          sum += glm::dvec3(img.at(x, y));
        }
      const glm::dvec3 ref = sum / double(kGrid * kGrid);
      for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(double(env.radiance[p][c]) - ref[c]));
    }
    // Texel values are in [0, 1]: the brute force misplaces a few of its
    // points along texel edges, about 1 / K of a pixel's area per edge.
    EXPECT_LT(worst, 4.0 / kGrid);
  }

  img.pixels.assign(img.pixels.size(), glm::vec3(0.25f));
  for (int order : {0, 2, 4, 6}) {
    const Environment env = environmentFromEquirect(img, order, 0.0f, 1.0f);
    float lo = 1.0f, hi = 0.0f;
    for (const glm::vec3& r : env.radiance) {
      lo = std::min({lo, r.x, r.y, r.z});
      hi = std::max({hi, r.x, r.y, r.z});
    }
    EXPECT_NEAR(lo, 0.25f, 2e-6f) << "Nside " << (1 << order);
    EXPECT_NEAR(hi, 0.25f, 2e-6f) << "Nside " << (1 << order);
  }
}

// Resampling keeps the map's total power to float rounding at every Nside,
// whatever the ratio of texel to pixel size, and does not depend on the yaw.
TEST(Environment, ResampleKeepsThePower) {
  std::mt19937 gen(3);
  std::exponential_distribution<float> value(1.0f);
  for (auto [w, h] : {std::pair{1, 1}, {3, 2}, {64, 32}, {1000, 333}}) {
    ImageRGB img;
    img.width = w;
    img.height = h;
    img.pixels.resize(size_t(w) * h);
    for (glm::vec3& p : img.pixels) p = glm::vec3(value(gen), value(gen), value(gen));
    const TexelIntegrals exact = texelIntegrals(img);
    for (int order : {0, 1, 4, 7}) {
      SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h) + " at Nside " + std::to_string(1 << order));
      const Environment env = environmentFromEquirect(img, order, 0.0f, 2.0f);
      EXPECT_LT(maxRelativeError(healpixIntegrals(env).power, 2.0 * exact.power), 1e-6);
      const Environment turned = environmentFromEquirect(img, order, 30.0f, 2.0f);
      EXPECT_TRUE(turned.radiance == env.radiance);
    }
  }
}

