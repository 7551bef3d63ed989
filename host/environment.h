// The environment light: radiance L(w) as a HEALPix map.
//
// The renderer's L(w) is piecewise constant: the value of the HEALPix pixel
// that contains w at the map's resolution. Every sampler, bound and reference
// integral uses this same function, so the trees' values at the leaves are
// exact, not approximations of a continuous map.
//
// Axes: world space is y-up. The HEALPix pole (its z axis) is world +y and
// its x, y axes are world z, x (a cyclic permutation, so a proper rotation).
// The yaw turns the environment about +y, counter-clockwise seen from above.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "image.h"
#include "tree.h"

namespace ht {

struct EnvironmentStats {
  uint64_t clampedNegativeTexels = 0;  // tiny negatives (lossy compression) set to 0
  uint64_t repairedNonFiniteTexels = 0;  // NaN/Inf values set to 0 (only when asked to repair)
  float minTexel = 0.0f;
  float maxTexel = 0.0f;
  double loadSeconds = 0.0;  // reading and checking the file
};

struct Environment {
  int order = 0;                    // Nside = 2^order
  float yawRadians = 0.0f;
  float cosYaw = 1.0f, sinYaw = 0.0f;
  std::vector<glm::vec3> radiance;  // per nested pixel, scale applied
  MaxAvgTree tree;                  // luminance of `radiance`
  double treeSeconds = 0.0;         // time spent building `tree`

  int nside() const { return 1 << order; }
  uint64_t pixelOf(const glm::vec3& worldDir) const;
  glm::vec3 eval(const glm::vec3& worldDir) const { return radiance[pixelOf(worldDir)]; }
  // The HEALPix frame of the map (pole = world +y, yaw undone) and back.
  glm::dvec3 toHealpixFrame(const glm::vec3& worldDir) const;
  glm::vec3 fromHealpixFrame(const glm::dvec3& h) const;
  // World direction of the point (dx, dy) in [0,1]^2 inside a pixel.
  glm::vec3 direction(int level, uint64_t pix, float dx, float dy) const;
  double pixelSolidAngle() const;
  // False for an all-black map: nothing to sample, every estimate is 0.
  bool hasLight() const { return tree.total() > 0.0; }
};

// Equirectangular convention of the input maps: pixel (x, y) covers
// u = (x + 0.5) / W, v = (y + 0.5) / H; theta = v pi from +y, phi = u 2 pi;
// direction (sin theta sin phi, cos theta, -sin theta cos phi).
glm::vec3 equirectDirection(double u, double v);
// (u, v) in [0,1)^2 of a world direction under the same convention.
void equirectUV(const glm::vec3& dir, double& u, double& v);

// Checks texels: refuses NaN/Inf (or, with repairNonFinite, sets them to 0
// and counts them) and negatives below -negativeTolerance (throws ht::Error
// naming the count and the first offender); clamps the remaining tiny
// negatives to 0.
EnvironmentStats sanitizeEnvironmentImage(ImageRGB& image, const std::string& name, bool repairNonFinite = false);

// Resamples an equirectangular map into HEALPix at 2^order, conserving
// energy: each HEALPix pixel holds the average over the pixel of the map
// taken as constant over each texel (up to quadrature error in latitude,
// which shrinks with the pixels and texels), and the map's total power
// (sum of texel radiance x texel solid angle) is kept exactly.
Environment environmentFromEquirect(const ImageRGB& image, int order, float yawDegrees, float scale);
// Rings of latitude per group of the resample's parallel work: about 1/64
// of them, at most 2^18 pixels (8 MiB of buffers per thread).
int64_t resampleRingsPerGroup(int order);
Environment environmentFromPixels(int order, std::vector<glm::vec3> radiance, float yawDegrees = 0.0f);
Environment constantEnvironment(int order, const glm::vec3& value);

}  // namespace ht
