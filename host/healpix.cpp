#include "healpix.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace ht::healpix {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kTwoPi = 6.283185307179586476925286766559;
constexpr double kInvHalfPi = 0.6366197723675813430755350534900574;
constexpr double kQuarterPi = 0.78539816339744830961566084581988;
constexpr double kTwoThird = 2.0 / 3.0;
// Marks "sin(theta) not supplied"; any value < -2 works.
constexpr double kNoSinTheta = -5.0;

// Per base face: jrll = ring coordinate (units of Nside, 0 at the north
// pole, 4 at the south pole) of the face's southern corner; jpll = the
// face's central phi in units of pi/4.
constexpr int kJrll[12] = {2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4};
constexpr int kJpll[12] = {1, 3, 5, 7, 0, 2, 4, 6, 1, 3, 5, 7};

// phi wrapped into [0, 2 pi); same branch structure as chealpix so that
// indices agree bit for bit.
double wrapPhi(double phi) {
  if (phi >= 0.0) return phi < kTwoPi ? phi : std::fmod(phi, kTwoPi);
  double t = std::fmod(phi, kTwoPi) + kTwoPi;
  return t == kTwoPi ? 0.0 : t;
}

uint64_t spreadBits(uint32_t v) {
  uint64_t x = v;
  x = (x | (x << 16)) & 0x0000FFFF0000FFFFull;
  x = (x | (x << 8)) & 0x00FF00FF00FF00FFull;
  x = (x | (x << 4)) & 0x0F0F0F0F0F0F0F0Full;
  x = (x | (x << 2)) & 0x3333333333333333ull;
  x = (x | (x << 1)) & 0x5555555555555555ull;
  return x;
}

uint32_t compressBits(uint64_t v) {
  uint64_t x = v & 0x5555555555555555ull;
  x = (x | (x >> 1)) & 0x3333333333333333ull;
  x = (x | (x >> 2)) & 0x0F0F0F0F0F0F0F0Full;
  x = (x | (x >> 4)) & 0x00FF00FF00FF00FFull;
  x = (x | (x >> 8)) & 0x0000FFFF0000FFFFull;
  x = (x | (x >> 16)) & 0x00000000FFFFFFFFull;
  return uint32_t(x);
}

// s = sin(theta) if known (> -2), used near the poles where 1 - |z| loses
// precision; this mirrors chealpix's ang2pix_nest_z_phi64.
void zphiToXYFImpl(int order, double z, double s, double phi, uint32_t& pix, uint32_t& piy, int& pface) {
  const int64_t nside = int64_t(1) << order;
  const double fn = double(nside);
  const double za = std::fabs(z);
  const double tt = wrapPhi(phi) * kInvHalfPi;  // [0, 4)
  int face;
  int64_t ix, iy;
  if (za <= kTwoThird) {
    const double t1 = fn * (0.5 + tt);
    const double t2 = fn * (z * 0.75);
    const int64_t jp = int64_t(t1 - t2);  // ascending edge line
    const int64_t jm = int64_t(t1 + t2);  // descending edge line
    const int64_t ifp = jp / nside;
    const int64_t ifm = jm / nside;
    face = int(ifp == ifm ? (ifp | 4) : (ifp < ifm ? ifp : ifm + 8));
    ix = jm & (nside - 1);
    iy = nside - (jp & (nside - 1)) - 1;
  } else {
    int ntt = int(tt);
    if (ntt >= 4) ntt = 3;
    const double tp = tt - ntt;
    const double tmp =
        s > -2.0 ? fn * s / std::sqrt((1.0 + za) / 3.0) : fn * std::sqrt(3.0 * (1.0 - za));
    int64_t jp = int64_t(tp * tmp);
    int64_t jm = int64_t((1.0 - tp) * tmp);
    if (jp >= nside) jp = nside - 1;  // rounding right at the face edge
    if (jm >= nside) jm = nside - 1;
    if (z >= 0.0) {
      face = ntt;
      ix = nside - jm - 1;
      iy = nside - jp - 1;
    } else {
      face = ntt + 8;
      ix = jp;
      iy = jm;
    }
  }
  pix = uint32_t(ix);
  piy = uint32_t(iy);
  pface = face;
}

uint64_t zphiToPixImpl(int order, double z, double s, double phi) {
  uint32_t ix, iy;
  int face;
  zphiToXYFImpl(order, z, s, phi, ix, iy, face);
  return xyfToPix(order, ix, iy, face);
}

// Inverse projection; also returns sin(theta) near the poles (else
// kNoSinTheta) because 1 - z^2 cancels catastrophically there.
void faceXYToZPhiSin(int face, double x, double y, double& z, double& phi, double& sth) {
  const double jr = kJrll[face] - x - y;
  double nr;
  sth = kNoSinTheta;
  if (jr < 1.0) {
    nr = jr;
    const double t = nr * nr / 3.0;
    z = 1.0 - t;
    if (z > 0.99) sth = std::sqrt(t * (2.0 - t));
  } else if (jr > 3.0) {
    nr = 4.0 - jr;
    const double t = nr * nr / 3.0;
    z = t - 1.0;
    if (z < -0.99) sth = std::sqrt(t * (2.0 - t));
  } else {
    nr = 1.0;
    z = (2.0 - jr) * (2.0 / 3.0);
  }
  double t = kJpll[face] * nr + x - y;
  if (t < 0.0) t += 8.0;
  if (t >= 8.0) t -= 8.0;
  phi = nr < 1e-15 ? 0.0 : kQuarterPi * t / nr;
}

double angleBetween(const glm::dvec3& a, const glm::dvec3& b) {
  const glm::dvec3 c(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
  return std::atan2(std::sqrt(c.x * c.x + c.y * c.y + c.z * c.z),
                    a.x * b.x + a.y * b.y + a.z * b.z);
}

}  // namespace

uint64_t zphiToPix(int order, double z, double phi) {
  return zphiToPixImpl(order, z, kNoSinTheta, phi);
}

void zphiToXYF(int order, double z, double phi, uint32_t& ix, uint32_t& iy, int& face) {
  zphiToXYFImpl(order, z, kNoSinTheta, phi, ix, iy, face);
}

uint64_t vecToPix(int order, const glm::dvec3& v) {
  // Same operation order as chealpix's vec2pix_nest64.
  const double xy2 = v.x * v.x + v.y * v.y;
  const double len = std::sqrt(xy2 + v.z * v.z);
  const double z = v.z / len;
  const double s = std::fabs(z) > 0.99 ? std::sqrt(xy2) / len : kNoSinTheta;
  return zphiToPixImpl(order, z, s, std::atan2(v.y, v.x));
}

void faceXYToZPhi(int face, double x, double y, double& z, double& phi) {
  double sth;
  faceXYToZPhiSin(face, x, y, z, phi, sth);
}

glm::dvec3 faceXYToVec(int face, double x, double y) {
  double z, phi, sth;
  faceXYToZPhiSin(face, x, y, z, phi, sth);
  if (sth < -2.0) sth = std::sqrt((1.0 - z) * (1.0 + z));
  return glm::dvec3(sth * std::cos(phi), sth * std::sin(phi), z);
}

glm::dvec3 pixToVec(int order, uint64_t pix, double dx, double dy) {
  uint32_t ix, iy;
  int face;
  pixToXYF(order, pix, ix, iy, face);
  const double fn = double(uint64_t(1) << order);
  return faceXYToVec(face, (ix + dx) / fn, (iy + dy) / fn);
}

void pixToZPhi(int order, uint64_t pix, double dx, double dy, double& z, double& phi) {
  uint32_t ix, iy;
  int face;
  pixToXYF(order, pix, ix, iy, face);
  const double fn = double(uint64_t(1) << order);
  faceXYToZPhi(face, (ix + dx) / fn, (iy + dy) / fn, z, phi);
}

uint64_t xyfToPix(int order, uint32_t ix, uint32_t iy, int face) {
  return (uint64_t(face) << (2 * order)) + spreadBits(ix) + (spreadBits(iy) << 1);
}

int64_t ringPixelCount(int order, int64_t ring) {
  const int64_t nside = int64_t(1) << order;
  return 4 * std::min({ring, 4 * nside - ring, nside});
}

void xyfToRing(int order, uint32_t ix, uint32_t iy, int face, int64_t& ring, int64_t& pos) {
  const int64_t nside = int64_t(1) << order;
  ring = kJrll[face] * nside - int64_t(ix) - int64_t(iy) - 1;
  // Pixels per quarter of the ring, and whether the ring's first pixel sits
  // half a pixel east (the odd rings of the equatorial zone).
  const int64_t quarter = std::min({ring, 4 * nside - ring, nside});
  const int64_t shift = quarter == nside ? ((ring - nside) & 1) : 0;
  int64_t p = (kJpll[face] * quarter + int64_t(ix) - int64_t(iy) + 1 + shift) / 2;
  if (p > 4 * nside) p -= 4 * nside;
  if (p < 1) p += 4 * nside;
  pos = p - 1;
}

void pixToXYF(int order, uint64_t pix, uint32_t& ix, uint32_t& iy, int& face) {
  const uint64_t local = pix & ((uint64_t(1) << (2 * order)) - 1);
  face = int(pix >> (2 * order));
  ix = compressBits(local);
  iy = compressBits(local >> 1);
}

Cone boundingCone(int order, uint64_t pix) {
  // The farthest point of a pixel from its centre lies on its boundary, and
  // for HEALPix pixels it is in fact a corner (checked against 4096 samples
  // per edge for every pixel of orders 0-5 and pole / face-corner / random
  // pixels up to order 13). The edge samples guard the bound anyway: were an
  // edge to bulge outward, its excess over the samples would be a chord
  // term of about r / (4 steps^2) ~ 1e-3 r, which the relative margin
  // covers; the absolute margin covers rounding of the points themselves.
  constexpr int kEdgeSteps = 16;
  constexpr double kRelMargin = 1e-3;
  constexpr double kAbsMargin = 1e-9;
  const glm::dvec3 axis = glm::normalize(pixToVec(order, pix, 0.5, 0.5));
  double maxAngle = 0.0;
  for (int k = 0; k < kEdgeSteps; ++k) {
    const double t = double(k) / kEdgeSteps;
    const double a0 = angleBetween(axis, pixToVec(order, pix, t, 0.0));
    const double a1 = angleBetween(axis, pixToVec(order, pix, 1.0, t));
    const double a2 = angleBetween(axis, pixToVec(order, pix, 1.0 - t, 1.0));
    const double a3 = angleBetween(axis, pixToVec(order, pix, 0.0, 1.0 - t));
    maxAngle = std::fmax(maxAngle, std::fmax(std::fmax(a0, a1), std::fmax(a2, a3)));
  }
  return Cone{axis, std::fmin(maxAngle * (1.0 + kRelMargin) + kAbsMargin, kPi)};
}

}  // namespace ht::healpix
