#include "brdf_table.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <tuple>

#include <tbb/parallel_for.h>

#include "sampling.h"
#include "error.h"

namespace ht {
namespace {

constexpr float kHalfPi = 0.5f * kPi;

glm::vec3 dirFromAngles(float theta, float phi) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

int binOf(float thetaO) {
  return std::clamp(int(thetaO / kHalfPi * BrdfTable::kThetaO), 0, BrdfTable::kThetaO - 1);
}

}  // namespace

BrdfTable::BrdfTable(const Material& m) {
  const int cells = kTheta * kPhi;
  maxima_.emplace_back(size_t(kThetaO) * cells);
  averages_.resize(size_t(kThetaO) * cells);
  const float dTheta = kHalfPi / kTheta, dPhi = kPi / kPhi;
  tbb::parallel_for(0, kThetaO, [&](int k) {
    // Outgoing elevations sampled over the bin, edges included.
    float thetaOs[3] = {k * kHalfPi / kThetaO, (k + 0.5f) * kHalfPi / kThetaO,
                        std::min((k + 1) * kHalfPi / kThetaO, kHalfPi - 1e-4f)};
    for (int it = 0; it < kTheta; ++it)
      for (int ip = 0; ip < kPhi; ++ip) {
        float mx = 0.0f;
        for (float tO : thetaOs) {
          glm::vec3 wo(std::sin(tO), 0.0f, std::cos(tO));
          glm::vec3 mirror(-wo.x, 0.0f, wo.z);
          auto consider = [&](float theta, float phi) {
            mx = std::max(mx, luminance(evalBsdf(m, wo, dirFromAngles(theta, phi))));
          };
          for (int a = 0; a <= 2; ++a)
            for (int b = 0; b <= 2; ++b) consider((it + a / 2.0f) * dTheta, (ip + b / 2.0f) * dPhi);
          // The point of the cell closest to the mirror direction, where lobes peak.
          float mTheta = std::acos(mirror.z), mPhi = kPi;
          consider(std::clamp(mTheta, it * dTheta, (it + 1) * dTheta), std::clamp(mPhi, ip * dPhi, (ip + 1) * dPhi));
        }
        size_t index = (size_t(k) * kTheta + it) * kPhi + ip;
        maxima_[0][index] = mx * kMargin;
        glm::vec3 wo(std::sin(thetaOs[1]), 0.0f, std::cos(thetaOs[1]));
        averages_[index] = luminance(evalBsdf(m, wo, dirFromAngles((it + 0.5f) * dTheta, (ip + 0.5f) * dPhi)));
      }
  });
  // Max pyramid: level l halves both axes.
  for (int t = kTheta, p = kPhi; t > 1 && p > 1; t /= 2, p /= 2) {
    const std::vector<float>& fine = maxima_.back();
    std::vector<float> coarse(size_t(kThetaO) * (t / 2) * (p / 2));
    for (int k = 0; k < kThetaO; ++k)
      for (int i = 0; i < t / 2; ++i)
        for (int j = 0; j < p / 2; ++j) {
          auto at = [&](int a, int b) { return fine[(size_t(k) * t + a) * p + b]; };
          coarse[(size_t(k) * (t / 2) + i) * (p / 2) + j] =
              std::max({at(2 * i, 2 * j), at(2 * i + 1, 2 * j), at(2 * i, 2 * j + 1), at(2 * i + 1, 2 * j + 1)});
        }
    maxima_.push_back(std::move(coarse));
  }
  levels_ = int(maxima_.size());
}

float BrdfTable::maxAt(int level, int k, int it, int ip) const {
  const int t = kTheta >> level, p = kPhi >> level;
  return maxima_[level][(size_t(k) * t + std::clamp(it, 0, t - 1)) * p + std::clamp(ip, 0, p - 1)];
}

float BrdfTable::bound(float thetaO, const glm::vec3& wi, float cosRadius, float sinRadius) const {
  const float radius = std::atan2(sinRadius, cosRadius);
  const float theta = std::acos(std::clamp(wi.z, -1.0f, 1.0f));
  if (theta - radius >= kHalfPi) return 0.0f;
  const float t0 = std::max(0.0f, theta - radius), t1 = std::min(kHalfPi, theta + radius);
  // Azimuths covered by the cone (all of them if it contains the pole).
  float p0 = 0.0f, p1 = kPi;
  const float sinTheta = std::sin(theta);
  if (radius < theta && sinRadius < sinTheta) {
    float phi = std::abs(std::atan2(wi.y, wi.x));
    float half = std::asin(sinRadius / sinTheta);
    float a = phi - half, b = phi + half;
    p0 = a < 0.0f ? 0.0f : (b > kPi ? std::min(a, 2.0f * kPi - b) : a);
    p1 = b > kPi ? kPi : (a < 0.0f ? std::max(b, -a) : b);
  }
  const float dTheta = kHalfPi / kTheta, dPhi = kPi / kPhi;
  int i0 = int(t0 / dTheta), i1 = std::min(kTheta - 1, int(t1 / dTheta));
  int j0 = int(p0 / dPhi), j1 = std::min(kPhi - 1, int(p1 / dPhi));
  // Coarsest pyramid level at which the rectangle spans at most 2 x 2 cells.
  int level = 0;
  while (level + 1 < levels_ && ((i1 >> level) - (i0 >> level) > 1 || (j1 >> level) - (j0 >> level) > 1)) ++level;
  const int k = binOf(thetaO);
  float m = 0.0f;
  for (int i = i0 >> level; i <= i1 >> level; ++i)
    for (int j = j0 >> level; j <= j1 >> level; ++j) m = std::max(m, maxAt(level, k, i, j));
  return m;
}

std::vector<float> BrdfTable::flattened() const {
  std::vector<float> out(averages_);
  for (const std::vector<float>& level : maxima_) out.insert(out.end(), level.begin(), level.end());
  return out;
}

float BrdfTable::average(float thetaO, const glm::vec3& wi) const {
  if (wi.z <= 0.0f) return 0.0f;
  const float dTheta = kHalfPi / kTheta, dPhi = kPi / kPhi;
  float x = std::acos(std::min(1.0f, wi.z)) / dTheta - 0.5f;
  float y = std::abs(std::atan2(wi.y, wi.x)) / dPhi - 0.5f;
  int i = int(std::floor(x)), j = int(std::floor(y));
  float fx = x - i, fy = y - j;
  const int k = binOf(thetaO);
  auto at = [&](int a, int b) {
    return averages_[(size_t(k) * kTheta + std::clamp(a, 0, kTheta - 1)) * kPhi + std::clamp(b, 0, kPhi - 1)];
  };
  return (1 - fx) * ((1 - fy) * at(i, j) + fy * at(i, j + 1)) + fx * ((1 - fy) * at(i + 1, j) + fy * at(i + 1, j + 1));
}

const BrdfTable& BrdfTables::at(size_t material) const {
  if (material >= perMaterial.size() || !perMaterial[material])
    throw Error("internal: BRDF table used but not prepared for this material");
  return *perMaterial[material];
}

}  // namespace ht
