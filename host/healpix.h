// HEALPix, nested scheme (Gorski et al. 2005), in double precision.
//
// The sphere is cut into 12 equal-area base faces; each face is a quadtree
// whose children of nested pixel p are 4p+0..3. At resolution Nside = 2^order
// a face holds Nside^2 pixels and the global nested index is
// face * Nside^2 + local. Every pixel of one resolution has the same solid
// angle 4 pi / (12 Nside^2).
//
// Written as small pure functions over plain values (no containers) so the
// same math can be ported line for line to GLSL.
#pragma once

#include <cstdint>
#include <glm/vec3.hpp>

namespace ht::healpix {

constexpr int kMaxOrder = 13;  // Nside up to 8192
constexpr int kFaces = 12;

struct Cone {
  glm::dvec3 axis;  // unit vector
  double radius;    // angular radius, radians
};

// Number of pixels on the sphere at this order: 12 * 4^order.
constexpr uint64_t pixelCount(int order) { return uint64_t(kFaces) << (2 * order); }
constexpr double pixelSolidAngle(int order) {
  return 4.0 * 3.14159265358979323846 / double(pixelCount(order));
}

// (z = cos theta, phi) -> nested index. phi in any range (wrapped).
// Bit-identical to chealpix's ang2pix_nest for |z| <= 0.99; nearer the
// poles chealpix uses sin(theta), which (z, phi) cannot carry.
uint64_t zphiToPix(int order, double z, double phi);
// The same pixel as (face, ix, iy).
void zphiToXYF(int order, double z, double phi, uint32_t& ix, uint32_t& iy, int& face);
// Unit (or any non-zero) vector -> nested index. Bit-identical to
// chealpix's vec2pix_nest64 (uses sin(theta) from x, y near the poles).
uint64_t vecToPix(int order, const glm::dvec3& v);

// Face coordinates: (x, y) in [0, 1]^2 over a base face, x along the
// pixel's ix axis. Maps to the sphere with the HEALPix equal-area projection.
void faceXYToZPhi(int face, double x, double y, double& z, double& phi);
glm::dvec3 faceXYToVec(int face, double x, double y);

// Point at fractional position (dx, dy) in [0,1]^2 inside pixel `pix`.
// Uniform (dx, dy) give points distributed uniformly in solid angle.
glm::dvec3 pixToVec(int order, uint64_t pix, double dx = 0.5, double dy = 0.5);
void pixToZPhi(int order, uint64_t pix, double dx, double dy, double& z, double& phi);

// Nested index <-> (face, ix, iy), 0 <= ix, iy < Nside.
uint64_t xyfToPix(int order, uint32_t ix, uint32_t iy, int face);
void pixToXYF(int order, uint64_t pix, uint32_t& ix, uint32_t& iy, int& face);

// Rings of latitude, numbered 1..4 Nside - 1 from the north pole: the
// pixel (face, ix, iy) is the pos-th (from 0, eastwards from phi = 0) of its
// ring, the ring scheme's index minus the ring's first one.
int64_t ringPixelCount(int order, int64_t ring);
void xyfToRing(int order, uint32_t ix, uint32_t iy, int face, int64_t& ring, int64_t& pos);

// Conservative bounding cone of a node: every direction inside pixel `pix`
// at `order` lies within `radius` of `axis`.
Cone boundingCone(int order, uint64_t pix);

}  // namespace ht::healpix
