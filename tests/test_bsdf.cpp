// Each lobe of evalBsdf against the models it claims, written out here again
// from the papers and integrated by deterministic quadrature: directional
// albedo, reciprocity, energy, and the normalisation of GGX's D.
//
// evalBsdf returns f(wo, wi) cos(theta_i) in the local frame (normal +z).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "bsdf.h"
#include "sampling.h"

using namespace ht;

namespace {

constexpr double kPiD = 3.14159265358979323846;

glm::dvec3 outgoing(double thetaDeg) {
  const double t = thetaDeg * kPiD / 180.0;
  return {std::sin(t), 0.0, std::cos(t)};
}

// Directional albedo of channel 0: the integral of evalBsdf over the upper
// hemisphere of wi, midpoint rule in (cos theta, phi), which covers the
// solid angle uniformly.
double albedo(const Material& m, const glm::dvec3& wo) {
  constexpr int kMu = 4096, kPhi = 512;
  double sum = 0.0;
  for (int i = 0; i < kMu; ++i) {
    const double mu = (i + 0.5) / kMu, st = std::sqrt(1.0 - mu * mu);
    for (int j = 0; j < kPhi; ++j) {
      const double phi = 2.0 * kPiD * (j + 0.5) / kPhi;
      const glm::vec3 wi(float(st * std::cos(phi)), float(st * std::sin(phi)), float(mu));
      sum += evalBsdf(m, glm::vec3(wo), wi).x;
    }
  }
  return sum * 2.0 * kPiD / (double(kMu) * kPhi);
}

Material lambert(float albedo) {
  Material m;
  m.type = MaterialType::Lambert;
  m.diffuse = glm::vec3(albedo);
  return m;
}

Material phong(float exponent, float ks, float kd = 0.0f) {
  Material m;
  m.type = MaterialType::Phong;
  m.exponent = exponent;
  m.specular = glm::vec3(ks);
  m.diffuse = glm::vec3(kd);
  return m;
}

Material ggxConductor(float alpha) {
  Material m;
  m.type = MaterialType::Ggx;
  m.alpha = alpha;
  m.specular = glm::vec3(1.0f);  // Schlick with F0 = 1: F = 1
  m.diffuse = glm::vec3(0.0f);
  return m;
}

// Normalised Phong (Lewis 1994): f = (n + 2) / (2 pi) cos^n(alpha), alpha
// the angle between wi and the mirror direction R of wo. Its albedo,
// integral of f cos+(theta_i), integrated in polar coordinates about R.
double phongAlbedoAboutMirror(double n, const glm::dvec3& wo) {
  const glm::dvec3 r(-wo.x, -wo.y, wo.z);
  const glm::dvec3 t1 = glm::normalize(glm::cross(std::abs(r.z) < 0.9 ? glm::dvec3(0, 0, 1) : glm::dvec3(1, 0, 0), r));
  const glm::dvec3 t2 = glm::cross(r, t1);
  constexpr int kMu = 8192, kPhi = 512;
  double sum = 0.0;
  for (int i = 0; i < kMu; ++i) {
    const double c = (i + 0.5) / kMu, s = std::sqrt(1.0 - c * c);  // cos(alpha) over [0, 1]
    const double lobe = (n + 2.0) / (2.0 * kPiD) * std::pow(c, n);
    for (int j = 0; j < kPhi; ++j) {
      const double beta = 2.0 * kPiD * (j + 0.5) / kPhi;
      const glm::dvec3 wi = c * r + s * (std::cos(beta) * t1 + std::sin(beta) * t2);
      sum += lobe * std::max(wi.z, 0.0);
    }
  }
  return sum * 2.0 * kPiD / (double(kMu) * kPhi);
}

// GGX / Trowbridge-Reitz (Walter et al. 2007): D(h) = alpha^2 / (pi cos^4
// theta_h (alpha^2 + tan^2 theta_h)^2); Smith Lambda(w) = (-1 + sqrt(1 +
// alpha^2 tan^2 theta)) / 2, height-correlated G2 = 1 / (1 + Lambda(wo) +
// Lambda(wi)) (Heitz 2014); f = F D G2 / (4 cos theta_o cos theta_i).
double ggxLambdaRef(const glm::dvec3& w, double alpha) {
  const double c2 = w.z * w.z, tan2 = (1.0 - c2) / c2;
  return 0.5 * (-1.0 + std::sqrt(1.0 + alpha * alpha * tan2));
}

double ggxDRef(const glm::dvec3& h, double alpha) {
  if (h.z <= 0.0) return 0.0;
  const double c2 = h.z * h.z, tan2 = (1.0 - c2) / c2, a2 = alpha * alpha;
  return a2 / (kPiD * c2 * c2 * (a2 + tan2) * (a2 + tan2));
}

// Albedo of the F = 1 GGX lobe integrated over half vectors instead of wi:
// dwi = 4 |wo.h| dwh, and with theta_h = atan(alpha sqrt(s / (1 - s))) the
// measure D(h) cos(theta_h) dwh becomes ds dphi / (2 pi), so the integrand
// left, G2 (wo.h) / (cos theta_o cos theta_h), is smooth in (s, phi).
double ggxAlbedoOverHalfVectors(double alpha, const glm::dvec3& wo) {
  constexpr int kS = 4096, kPhi = 512;
  double sum = 0.0;
  for (int i = 0; i < kS; ++i) {
    const double s = (i + 0.5) / kS;
    const double th = std::atan(alpha * std::sqrt(s / (1.0 - s)));
    for (int j = 0; j < kPhi; ++j) {
      const double phi = 2.0 * kPiD * (j + 0.5) / kPhi;
      const glm::dvec3 h(std::sin(th) * std::cos(phi), std::sin(th) * std::sin(phi), std::cos(th));
      const double oh = glm::dot(wo, h);
      if (oh <= 0.0) continue;
      const glm::dvec3 wi = 2.0 * oh * h - wo;
      if (wi.z <= 0.0) continue;
      const double g2 = 1.0 / (1.0 + ggxLambdaRef(wo, alpha) + ggxLambdaRef(wi, alpha));
      sum += g2 * oh / (wo.z * h.z);
    }
  }
  return sum / (double(kS) * kPhi);
}

}  // namespace

TEST(Bsdf, LambertAlbedoIsItsAlbedo) {
  for (float a : {0.2f, 0.8f, 1.0f})
    for (double theta : {0.0, 45.0, 85.0}) EXPECT_NEAR(albedo(lambert(a), outgoing(theta)), a, 1e-4) << a << " " << theta;
}

// At normal incidence the normalised lobe integrates to exactly ks against
// the cosine; elsewhere the horizon clips it, which the quadrature about the
// mirror direction measures independently. Without the +2 (n + 1 instead),
// n = 10 would be 8 % low.
TEST(Bsdf, PhongAlbedoMatchesTheNormalisedLobe) {
  for (float n : {1.0f, 10.0f, 100.0f})
    for (double theta : {0.0, 30.0, 60.0, 80.0}) {
      SCOPED_TRACE("n " + std::to_string(n) + " theta_o " + std::to_string(theta));
      const glm::dvec3 wo = outgoing(theta);
      const double got = albedo(phong(n, 0.7f), wo);
      const double ref = 0.7 * phongAlbedoAboutMirror(n, wo);
      if (theta == 0.0) {
        EXPECT_NEAR(ref, 0.7, 2e-3);
      }
      EXPECT_NEAR(got, ref, 2e-3);
      EXPECT_LE(got, 0.7 + 2e-3);
    }
}

// The conductor lobe with F = 1 against the same model integrated over half
// vectors. A D missing its 1 / pi would be off by a factor pi; a separable
// G instead of the height-correlated one by up to a few percent at grazing
// angles and high roughness.
TEST(Bsdf, GgxConductorAlbedoMatchesTheModel) {
  for (float alpha : {0.1f, 0.3f, 0.6f, 1.0f})
    for (double theta : {0.0, 30.0, 60.0, 80.0}) {
      SCOPED_TRACE("alpha " + std::to_string(alpha) + " theta_o " + std::to_string(theta));
      const glm::dvec3 wo = outgoing(theta);
      const double got = albedo(ggxConductor(alpha), wo);
      const double ref = ggxAlbedoOverHalfVectors(alpha, wo);
      EXPECT_NEAR(got, ref, 2e-3 * std::max(ref, 0.1));
      EXPECT_LE(got, 1.0 + 2e-3);
      // A smooth conductor reflects nearly everything at normal incidence.
      if (alpha <= 0.1f && theta == 0.0) {
        EXPECT_GT(got, 0.98);
      }
    }
}

// The project's D against Walter et al.'s form pointwise, and normalised:
// the integral of D(h) cos(theta_h) over the hemisphere of h is 1.
TEST(Bsdf, GgxDistributionIsNormalised) {
  for (float alpha : {0.05f, 0.2f, 0.5f, 1.0f}) {
    SCOPED_TRACE("alpha " + std::to_string(alpha));
    constexpr int kMu = 1 << 16;
    double sum = 0.0;
    for (int i = 0; i < kMu; ++i) {
      const double mu = (i + 0.5) / kMu;
      const glm::vec3 h(float(std::sqrt(1.0 - mu * mu)), 0.0f, float(mu));
      const double d = ggxD(h, alpha);
      const double ref = ggxDRef(glm::dvec3(h), alpha);
      ASSERT_NEAR(d, ref, 1e-4 * ref + 1e-7) << "cos theta_h " << mu;  // float rounding
      sum += d * mu;  // isotropic: the phi integral is 2 pi
    }
    EXPECT_NEAR(sum * 2.0 * kPiD / kMu, 1.0, 1e-3);
  }
}

// f(wo, wi) = f(wi, wo) for every lobe and mixture, over random direction
// pairs (evalBsdf carries cos(theta_i), which is divided out).
TEST(Bsdf, Reciprocity) {
  std::vector<Material> materials = {lambert(0.8f), phong(1.0f, 0.5f, 0.3f), phong(50.0f, 0.9f),
                                     ggxConductor(0.1f), ggxConductor(0.7f)};
  Material dielectric = ggxConductor(0.3f);
  dielectric.specular = glm::vec3(0.04f);
  dielectric.diffuse = glm::vec3(0.5f, 0.3f, 0.2f);
  materials.push_back(dielectric);
  std::mt19937 gen(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  auto direction = [&] {
    const float mu = 0.02f + 0.98f * u(gen), phi = 2.0f * float(kPiD) * u(gen), st = std::sqrt(1.0f - mu * mu);
    return glm::vec3(st * std::cos(phi), st * std::sin(phi), mu);
  };
  for (size_t k = 0; k < materials.size(); ++k)
    for (int i = 0; i < 2000; ++i) {
      const glm::vec3 a = direction(), b = direction();
      const glm::vec3 fab = evalBsdf(materials[k], a, b) / b.z, fba = evalBsdf(materials[k], b, a) / a.z;
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(fab[c], fba[c], 1e-4f * std::max(fab[c], 1.0f)) << "material " << k;
    }
}

// Energy: no lobe or mixture whose weights sum to at most 1 reflects more
// than it receives, at any angle.
TEST(Bsdf, AlbedoAtMostOne) {
  const std::vector<Material> materials = {lambert(1.0f), phong(2.0f, 0.5f, 0.5f), phong(20.0f, 1.0f),
                                           ggxConductor(0.05f), ggxConductor(1.0f)};
  for (size_t k = 0; k < materials.size(); ++k)
    for (double theta : {0.0, 45.0, 75.0, 89.0}) EXPECT_LE(albedo(materials[k], outgoing(theta)), 1.0 + 2e-3) << k;
}
