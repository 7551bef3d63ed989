// Nested HEALPix (host/healpix.cpp) in GLSL, for the environment lookups.
//
// Precision (HT_FP64 = 1, devices with shaderFloat64, lavapipe included):
// direction -> pixel runs in double like the CPU, with atan2 written out
// below (GLSL has no double-precision trigonometry; within 3 ulp of glibc,
// so an index can only differ for a direction within ~1e-15 of a pixel
// border). Pixel -> direction runs in double, cos/sin of phi too (cosSinD):
// the direction differs from the CPU's by a few ulp of a double.
// HT_FP64 = 0 (devices without it) does everything in float: indices then
// also differ for directions within ~1e-6 pixel widths of a border.
#ifndef HT_HEALPIX_GLSL
#define HT_HEALPIX_GLSL

#if HT_FP64
#define hreal double
#define hvec3 dvec3
const double kHpPi = 3.14159265358979323846lf;
const double kHpHalfPi = 1.5707963267948966192313216916398lf;
const double kHpTwoPi = 6.283185307179586476925286766559lf;
const double kHpInvHalfPi = 0.6366197723675813430755350534900574lf;
const double kHpQuarterPi = 0.78539816339744830961566084581988lf;
const double kHpTwoThird = 2.0lf / 3.0lf;
const double kHpPolar = 0.99lf;   // |z| above which sin(theta) is carried separately
const double kHpTiny = 1e-15lf;
#else
#define hreal float
#define hvec3 vec3
const float kHpTwoPi = 6.283185307179586476925286766559;
const float kHpInvHalfPi = 0.6366197723675813430755350534900574;
const float kHpQuarterPi = 0.78539816339744830961566084581988;
const float kHpTwoThird = 2.0 / 3.0;
const float kHpPolar = 0.99;
const float kHpTiny = 1e-15;
#endif
const hreal kHpNoSinTheta = -5.0;

// The reference's jrll (2, 2, 2, 2, 3, ..., 4) and jpll (1, 3, 5, 7, 0, 2,
// 4, 6, 1, 3, 5, 7) per face, by arithmetic: llvmpipe builds a constant
// array indexed per lane afresh at each use, lane by lane.
int hpJrll(uint face) { return 2 + int(face >> 2); }
int hpJpll(uint face) { return int(2u * (face & 3u) + 1u - ((face >> 2) & 1u)); }

#if HT_FP64
// atan(t) for t in [0, 1]: atan(c) + atan((t - c) / (1 + t c)) with c the
// nearest multiple of 1/8, the remainder (|u| <= 1/16) by its Taylor series
// to u^15 (truncation below 2^-64 relative).
// atan(k / 8) for k = 0..8, by selects rather than a constant array (as hpJrll).
double atanEighth(int k) {
  double lo = k <= 1 ? (k == 0 ? 0.0lf : 0.12435499454676144lf)
                     : k == 2 ? 0.24497866312686414lf : k == 3 ? 0.35877067027057225lf : 0.46364760900080609lf;
  double hi = k <= 6 ? (k == 5 ? 0.55859931534356244lf : 0.64350110879328437lf)
                     : k == 7 ? 0.71882999962162453lf : 0.78539816339744828lf;
  return k <= 4 ? lo : hi;
}
precise double atanUnit(double t) {
  int k = int(floor(t * 8.0lf + 0.5lf));
  double c = double(k) * 0.125lf;
  double u = (t - c) / (1.0lf + t * c);
  double u2 = u * u;
  double p = -1.0lf / 15.0lf;
  p = p * u2 + 1.0lf / 13.0lf;
  p = p * u2 - 1.0lf / 11.0lf;
  p = p * u2 + 1.0lf / 9.0lf;
  p = p * u2 - 1.0lf / 7.0lf;
  p = p * u2 + 1.0lf / 5.0lf;
  p = p * u2 - 1.0lf / 3.0lf;
  return atanEighth(k) + (u + u * (u2 * p));
}
bool signBit(double x) { return (unpackDouble2x32(x).y & 0x80000000u) != 0u; }
// atan2 with C's conventions for signed zeros.
precise double atan2d(double y, double x) {
  double ax = abs(x), ay = abs(y);
  bool swapped = ay > ax;
  double a = (ax == 0.0lf && ay == 0.0lf) ? 0.0lf : atanUnit(swapped ? ax / ay : ay / ax);
  if (swapped) a = kHpHalfPi - a;
  if (signBit(x)) a = kHpPi - a;
  return signBit(y) ? -a : a;
}
#define hpAtan2 atan2d
// cos and sin of x (|x| <= 4 pi): x = k pi/2 + r with pi/2 in two parts,
// |r| <= pi/4, and r's Taylor series to r^16 / r^17 (truncation below
// 2^-60). Within a few ulp of glibc's on every device, where GLSL's cos and
// sin are single precision, and on some drivers (NVIDIA's) only to ~1e-6.
void cosSinD(double x, out double c, out double s) {
  precise double k = floor(x * kHpInvHalfPi + 0.5lf);
  precise double r = (x - k * 1.5707963267948966lf) - k * 6.123233995736766e-17lf;
  precise double r2 = r * r;
  precise double ps = -1.0lf / 1307674368000.0lf;
  ps = ps * r2 + 1.0lf / 6227020800.0lf;
  ps = ps * r2 - 1.0lf / 39916800.0lf;
  ps = ps * r2 + 1.0lf / 362880.0lf;
  ps = ps * r2 - 1.0lf / 5040.0lf;
  ps = ps * r2 + 1.0lf / 120.0lf;
  ps = ps * r2 - 1.0lf / 6.0lf;
  precise double sr = r + r * (r2 * ps);
  precise double pc = 1.0lf / 20922789888000.0lf;
  pc = pc * r2 - 1.0lf / 87178291200.0lf;
  pc = pc * r2 + 1.0lf / 479001600.0lf;
  pc = pc * r2 - 1.0lf / 3628800.0lf;
  pc = pc * r2 + 1.0lf / 40320.0lf;
  pc = pc * r2 - 1.0lf / 720.0lf;
  pc = pc * r2 + 1.0lf / 24.0lf;
  pc = pc * r2 - 0.5lf;
  precise double cr = 1.0lf + r2 * pc;
  int q = int(k) & 3;
  c = q == 0 ? cr : q == 1 ? -sr : q == 2 ? -cr : sr;
  s = q == 0 ? sr : q == 1 ? cr : q == 2 ? -sr : -cr;
}
#else
#define hpAtan2 atan
#endif

uint spreadBits(uint v) {
  v = (v | (v << 8)) & 0x00FF00FFu;
  v = (v | (v << 4)) & 0x0F0F0F0Fu;
  v = (v | (v << 2)) & 0x33333333u;
  v = (v | (v << 1)) & 0x55555555u;
  return v;
}
uint compressBits(uint v) {
  v &= 0x55555555u;
  v = (v | (v >> 1)) & 0x33333333u;
  v = (v | (v >> 2)) & 0x0F0F0F0Fu;
  v = (v | (v >> 4)) & 0x00FF00FFu;
  v = (v | (v >> 8)) & 0x0000FFFFu;
  return v;
}

// 32-bit indices: 12 * 4^order < 2^32 for order <= 13.
uint xyfToPix(uint order, uint ix, uint iy, uint face) {
  return (face << (2u * order)) + spreadBits(ix) + (spreadBits(iy) << 1);
}
void pixToXYF(uint order, uint pix, out uint ix, out uint iy, out uint face) {
  uint local = pix & ((1u << (2u * order)) - 1u);
  face = pix >> (2u * order);
  ix = compressBits(local);
  iy = compressBits(local >> 1);
}

// phi from atan2 lies in [-pi, pi]: fmod(phi, 2 pi) = phi for negative phi.
precise hreal wrapPhi(hreal phi) {
  if (phi >= 0.0) return phi;
  hreal t = phi + kHpTwoPi;
  return t == kHpTwoPi ? 0.0 : t;
}

// healpix::zphiToPixImpl; s = sin(theta) when supplied (> -2).
uint zphiToPix(uint order, hreal z, hreal s, hreal phi) {
  int nside = 1 << order;
  precise hreal fn = hreal(nside);
  precise hreal za = abs(z);
  precise hreal tt = wrapPhi(phi) * kHpInvHalfPi;
  int face, ix, iy;
  if (za <= kHpTwoThird) {
    precise hreal t1 = fn * (0.5 + tt);
    precise hreal t2 = fn * (z * 0.75);
    precise hreal sumMinus = t1 - t2;
    precise hreal sumPlus = t1 + t2;
    int jp = int(sumMinus);
    int jm = int(sumPlus);
    int ifp = jp >> order;
    int ifm = jm >> order;
    face = ifp == ifm ? (ifp | 4) : (ifp < ifm ? ifp : ifm + 8);
    ix = jm & (nside - 1);
    iy = nside - (jp & (nside - 1)) - 1;
  } else {
    int ntt = min(int(tt), 3);
    precise hreal tp = tt - hreal(ntt);
    precise hreal tmp = s > -2.0 ? fn * s / sqrt((1.0 + za) / 3.0) : fn * sqrt(3.0 * (1.0 - za));
    precise hreal a = tp * tmp;
    precise hreal b = (1.0 - tp) * tmp;
    int jp = min(int(a), nside - 1);
    int jm = min(int(b), nside - 1);
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
  return xyfToPix(order, uint(ix), uint(iy), uint(face));
}

// healpix::vecToPix (chealpix's operation order).
uint vecToPix(uint order, hvec3 v) {
  precise hreal xy2 = v.x * v.x + v.y * v.y;
  precise hreal len = sqrt(xy2 + v.z * v.z);
  precise hreal z = v.z / len;
  precise hreal s = abs(z) > kHpPolar ? sqrt(xy2) / len : kHpNoSinTheta;
  return zphiToPix(order, z, s, hpAtan2(v.y, v.x));
}

// healpix::faceXYToZPhiSin.
void faceXYToZPhiSin(uint face, hreal x, hreal y, out hreal z, out hreal phi, out hreal sth) {
  precise hreal jr = hreal(hpJrll(face)) - x - y;
  precise hreal nr;
  precise hreal zz;
  precise hreal st = kHpNoSinTheta;
  if (jr < 1.0) {
    nr = jr;
    precise hreal t = nr * nr / 3.0;
    zz = 1.0 - t;
    if (zz > kHpPolar) st = sqrt(t * (2.0 - t));
  } else if (jr > 3.0) {
    nr = 4.0 - jr;
    precise hreal t = nr * nr / 3.0;
    zz = t - 1.0;
    if (zz < -kHpPolar) st = sqrt(t * (2.0 - t));
  } else {
    nr = 1.0;
    zz = (2.0 - jr) * kHpTwoThird;
  }
  precise hreal t = hreal(hpJpll(face)) * nr + x - y;
  if (t < 0.0) t += 8.0;
  if (t >= 8.0) t -= 8.0;
  precise hreal p = nr < kHpTiny ? 0.0 : kHpQuarterPi * t / nr;
  z = zz;
  phi = p;
  sth = st;
}

// healpix::pixToVec in the HEALPix frame.
hvec3 pixToVecAt(uint order, uint pix, hreal dx, hreal dy) {
  uint ix, iy, face;
  pixToXYF(order, pix, ix, iy, face);
  precise hreal fn = hreal(1u << order);
  precise hreal x = (hreal(ix) + dx) / fn;
  precise hreal y = (hreal(iy) + dy) / fn;
  hreal z, phi, sth;
  faceXYToZPhiSin(face, x, y, z, phi, sth);
  precise hreal st = sth < -2.0 ? sqrt((1.0 - z) * (1.0 + z)) : sth;
#if HT_FP64
  double cphi, sphi;
  cosSinD(phi, cphi, sphi);
  precise hvec3 v = hvec3(st * cphi, st * sphi, z);
#else
  precise hvec3 v = hvec3(st * cos(phi), st * sin(phi), z);
#endif
  return v;
}
hvec3 pixToVec(uint order, uint pix, float dx, float dy) { return pixToVecAt(order, pix, hreal(dx), hreal(dy)); }

#endif
