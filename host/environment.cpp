#include "environment.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fmt/format.h>

#include <tbb/parallel_for.h>

#include "healpix.h"
#include "sampling.h"

namespace ht {
namespace {

constexpr double kPiD = 3.14159265358979323846;

void finish(Environment& env) {
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<float> lum(env.radiance.size());
  for (size_t i = 0; i < lum.size(); ++i) lum[i] = luminance(env.radiance[i]);
  env.tree = buildMaxAvgTree(env.order, lum);
  env.treeSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void setYaw(Environment& env, float yawDegrees) {
  env.yawRadians = float(double(yawDegrees) * kPiD / 180.0);
  env.cosYaw = std::cos(env.yawRadians);
  env.sinYaw = std::sin(env.yawRadians);
}

}  // namespace

// World (y-up) -> HEALPix frame (pole = world +y), after undoing the yaw.
glm::dvec3 Environment::toHealpixFrame(const glm::vec3& w) const {
  double x = double(cosYaw) * w.x - double(sinYaw) * w.z;
  double z = double(sinYaw) * w.x + double(cosYaw) * w.z;
  return {z, x, double(w.y)};
}

glm::vec3 Environment::fromHealpixFrame(const glm::dvec3& h) const {
  double x = h.y, z = h.x;
  return glm::vec3(float(cosYaw * x + sinYaw * z), float(h.z), float(-sinYaw * x + cosYaw * z));
}

uint64_t Environment::pixelOf(const glm::vec3& worldDir) const {
  return healpix::vecToPix(order, toHealpixFrame(worldDir));
}

glm::vec3 Environment::direction(int level, uint64_t pix, float dx, float dy) const {
  return fromHealpixFrame(healpix::pixToVec(level, pix, dx, dy));
}

double Environment::pixelSolidAngle() const { return healpix::pixelSolidAngle(order); }

glm::vec3 equirectDirection(double u, double v) {
  double theta = v * kPiD, phi = u * 2.0 * kPiD;
  return glm::vec3(float(std::sin(theta) * std::sin(phi)), float(std::cos(theta)),
                   float(-std::sin(theta) * std::cos(phi)));
}

void equirectUV(const glm::vec3& d, double& u, double& v) {
  double len = std::sqrt(double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z);
  double phi = std::atan2(double(d.x), -double(d.z));
  if (phi < 0.0) phi += 2.0 * kPiD;
  u = std::min(phi / (2.0 * kPiD), std::nextafter(1.0, 0.0));
  v = std::min(std::acos(std::clamp(double(d.y) / len, -1.0, 1.0)) / kPiD, std::nextafter(1.0, 0.0));
}

EnvironmentStats sanitizeEnvironmentImage(ImageRGB& image, const std::string& name, bool repairNonFinite) {
  EnvironmentStats stats;
  uint64_t nonFinite = 0;
  size_t firstNonFinite = 0;
  double sum = 0.0;
  float lo = INFINITY, hi = -INFINITY;
  for (size_t i = 0; i < image.pixels.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      float& v = image.pixels[i][c];
      if (!std::isfinite(v)) {
        if (nonFinite++ == 0) firstNonFinite = i;
        if (repairNonFinite) v = 0.0f;
        continue;
      }
      lo = std::min(lo, v);
      hi = std::max(hi, v);
      sum += std::max(0.0f, v);
    }
  }
  stats.repairedNonFiniteTexels = repairNonFinite ? nonFinite : 0;
  if (nonFinite > 0 && !repairNonFinite)
    throw Error(fmt::format("{}: {} NaN/Inf texel value(s), first at pixel ({}, {})", name, nonFinite,
                            firstNonFinite % image.width, firstNonFinite / image.width));
  // Lossy EXR compression (DWAB) leaves tiny negatives (down to -4e-3 in the
  // shipped maps); below -max(0.01, 1% of the mean) the map is broken.
  double mean = image.pixels.empty() ? 0.0 : sum / (3.0 * double(image.pixels.size()));
  float tolerance = float(std::max(1e-2 * mean, 1e-2));
  for (size_t i = 0; i < image.pixels.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      float& v = image.pixels[i][c];
      if (v >= 0.0f) continue;
      if (v < -tolerance)
        throw Error(fmt::format("{}: negative texel value {} at pixel ({}, {}) (tolerance -{})", name, v,
                                i % image.width, i / image.width, tolerance));
      v = 0.0f;
      ++stats.clampedNegativeTexels;
    }
  }
  stats.minTexel = image.pixels.empty() ? 0.0f : lo;
  stats.maxTexel = image.pixels.empty() ? 0.0f : hi;
  return stats;
}

Environment environmentFromEquirect(const ImageRGB& image, int order, float yawDegrees, float scale,
                                    int supersample) {
  Environment env;
  env.order = order;
  setYaw(env, 0.0f);
  env.radiance.resize(healpix::pixelCount(order));
  const int n = std::max(1, supersample);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, env.radiance.size()), [&](const auto& range) {
    for (uint64_t p = range.begin(); p != range.end(); ++p) {
      glm::dvec3 sum(0.0);
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          glm::vec3 d = env.direction(order, p, (i + 0.5f) / n, (j + 0.5f) / n);
          double u, v;
          equirectUV(d, u, v);
          int x = std::min(int(u * image.width), image.width - 1);
          int y = std::min(int(v * image.height), image.height - 1);
          sum += glm::dvec3(image.at(x, y));
        }
      env.radiance[p] = glm::vec3(sum * (double(scale) / (n * n)));
    }
  });
  setYaw(env, yawDegrees);
  finish(env);
  return env;
}

Environment environmentFromPixels(int order, std::vector<glm::vec3> radiance, float yawDegrees) {
  Environment env;
  env.order = order;
  env.radiance = std::move(radiance);
  setYaw(env, yawDegrees);
  finish(env);
  return env;
}

Environment constantEnvironment(int order, const glm::vec3& value) {
  return environmentFromPixels(order, std::vector<glm::vec3>(healpix::pixelCount(order), value));
}

}  // namespace ht
