// The `ris` (host/ris.cpp), `tsis` (host/tsis.cpp), `wis` and `wis-biased`
// (host/wis.cpp) estimates, draw for draw as on the CPU.
//
// tsis and wis need doubles (tsis's summed-area table is one: differences
// of a float table would lose dim pixels next to a sun; wis's tree sums
// likewise) and exist in the HT_FP64 shader only; the host refuses them on
// devices without shaderFloat64.
#ifndef HT_COMPETITORS_GLSL
#define HT_COMPETITORS_GLSL

#include "shading.glsl"

#if HT_FP64
#define accreal double
#else
#define accreal float
#endif

// ---------------------------------------------------------------- ris

struct RisCandidate {
  vec3 dir;
  vec3 radiance;
  vec3 fcos;
  float mixturePdf;  // 0.5 p_env + 0.5 p_brdf
  float target;      // luminance(radiance * fcos)
};

RisCandidate risEvaluate(Shading sh, vec3 dir, vec3 radiance, float envPdf) {
  RisCandidate c;
  c.dir = dir;
  c.radiance = radiance;
  precise vec3 local = toLocal(sh.frame, dir);
  c.fcos = evalBsdf(sh.material, sh.woLocal, local);
  precise float mixture = 0.5 * envPdf + 0.5 * bsdfPdf(sh.material, sh.woLocal, local);
  c.mixturePdf = mixture;
  precise vec3 product = radiance * c.fcos;
  c.target = luminance(product);
  return c;
}

// RisSampler::candidate: u.x below 1/2 takes the environment, else the BRDF.
RisCandidate risCandidate(Shading sh, inout Sampler smp) {
#if HT_FP64
  dvec2 u = samplerNext2DPrecise(smp);
#else
  vec2 u = samplerNext2DPrecise(smp);
#endif
  if (u.x < 0.5) {
    precise hreal x = hreal(2.0) * u.x;
    EnvSample s = sampleEnvironment(min(x, kEnvBelowOne), u.y);
    return risEvaluate(sh, s.dir, s.pdf > 0.0 ? envRadiance(s.pixel) : vec3(0.0), s.pdf);
  }
  precise hreal x = hreal(2.0) * u.x - hreal(1.0);
  vec2 ub = vec2(min(float(x), uintBitsToFloat(0x3f7fffffu)), float(u.y));
  precise vec3 dir = toWorld(sh.frame, sampleBsdf(sh.material, sh.woLocal, ub));
  return risEvaluate(sh, dir, envEval(dir), environmentPdf(dir));
}

// RisSampler::sample for sample i: `m` candidates streamed through a
// one-element reservoir; the one kept and its contribution weight (0: none).
RisCandidate risSample(Shading sh, uint i, uint m, inout Sampler smp, out accreal weight) {
  RisCandidate chosen;
  chosen.dir = vec3(0.0, 1.0, 0.0);
  chosen.radiance = vec3(0.0);
  chosen.fcos = vec3(0.0);
  chosen.mixturePdf = 0.0;
  chosen.target = 0.0;
  precise accreal weightSum = 0.0;
  vec2 draws = vec2(0.0);
  for (uint k = 0u; k < m; ++k) {
    // The point of sample i m + k, the draws of sample i.
    samplerStart(smp, i * m + k);
    RisCandidate c = risCandidate(sh, smp);
    precise accreal w = c.target > 0.0 && c.mixturePdf > 0.0 ? accreal(c.target) / accreal(c.mixturePdf) : 0.0;
    if ((k & 1u) == 0u) {
      samplerStart(smp, i);
      smp.dimension = 1u + k / 2u;
      draws = samplerNextIndependent2D(smp);
    }
    float u = (k & 1u) == 0u ? draws.x : draws.y;
    if (w <= 0.0) continue;
    weightSum += w;
    precise accreal scaled = accreal(u) * weightSum;
    if (scaled < w) chosen = c;
  }
  precise accreal contribution = chosen.target > 0.0 ? weightSum / (accreal(m) * accreal(chosen.target)) : 0.0;
  weight = contribution;
  return chosen;
}

// estimateRis, samples [begin, end): per sample, one resampled candidate
// and one shadow ray for it.
uint risSamples(Shading sh, uint begin, uint end, uint candidates, inout Sampler smp, inout accvec3 sum,
                inout uint directions) {
  uint m = max(candidates, 1u);
  uint i = begin;
  for (; i < end; ++i) {
    accreal weight;
    RisCandidate chosen = risSample(sh, i, m, smp, weight);
    directions += m;
    if (!(weight > 0.0)) continue;
    ++gShadowRays;
    if (!occluded(sh.origin, chosen.dir)) {
      precise vec3 product = chosen.radiance * chosen.fcos;
      precise accvec3 total = sum + accvec3(product) * weight;
      sum = total;
    }
  }
  return i - begin;
}

// ---------------------------------------------------------------- tsis
#if HT_FP64

#define kBelowOneD packDouble2x32(uvec2(0xFFFFFFFFu, 0x3FEFFFFFu))  // 1 - 2^-53

// HealpixFrameBrdf: f cos for directions in the HEALPix frame.
struct HpBrdf {
  Frame frame;
  vec3 woLocal;
  vec3 n, wo;
};

HpBrdf makeHpBrdf(vec3 normalWorld, vec3 woWorld) {
  HpBrdf b;
  b.frame = makeFrame(normalize3(vec3(toHealpixFrame(normalWorld))));
  b.n = b.frame.n;
  b.wo = normalize3(vec3(toHealpixFrame(woWorld)));
  b.woLocal = toLocal(b.frame, b.wo);
  return b;
}
float hpBrdfValue(HpBrdf b, GpuMaterial m, vec3 dirHp) {
  return luminance(evalBsdf(m, b.woLocal, toLocal(b.frame, dirHp)));
}
precise float hpBrdfScale(GpuMaterial m) {
  precise float s = luminance(m.diffuse);
  if (m.type != HT_MATERIAL_LAMBERT) s += luminance(m.specular);
  return s * kInvPi;
}

// sin and cos of phi in [0, 2 pi] in double: a Cody-Waite reduction to
// [-pi/4, pi/4] and fdlibm's kernels, within an ulp of glibc. Float cos and
// sin would move the partition's evaluation points by 1e-7, which a sharp
// lobe (cos^n) turns into region weights 1e-4 off the CPU's.
void sinCosD(double phi, out double sinPhi, out double cosPhi) {
  precise double k = floor(phi * 6.36619772367581382433e-01lf + 0.5lf);
  precise double x = (phi - k * 1.57079632673412561417e+00lf) - k * 6.07710050650619224932e-11lf;
  precise double z = x * x;
  precise double sr = 8.33333333332248946124e-03lf +
                      z * (-1.98412698298579493134e-04lf +
                           z * (2.75573137070700676789e-06lf +
                                z * (-2.50507602534068634195e-08lf + z * 1.58969099521155010221e-10lf)));
  precise double sn = x + z * x * (-1.66666666666666324348e-01lf + z * sr);
  precise double cr = z * (4.16666666666666019037e-02lf +
                           z * (-1.38888888888741095749e-03lf +
                                z * (2.48015872894767294178e-05lf +
                                     z * (-2.75573143513906633035e-07lf +
                                          z * (2.08757232129817482790e-09lf + z * -1.13596475577881948265e-11lf)))));
  uint high = unpackDouble2x32(abs(x)).y;
  precise double cs;
  if (high < 0x3FD33333u) {
    cs = 1.0lf - (0.5lf * z - z * cr);
  } else {
    double qx = high > 0x3FE90000u ? 0.28125lf : packDouble2x32(uvec2(0u, high - 0x00200000u));
    cs = (1.0lf - qx) - ((0.5lf * z - qx) - z * cr);
  }
  uint quadrant = uint(k) & 3u;
  sinPhi = quadrant == 0u ? sn : quadrant == 1u ? cs : quadrant == 2u ? -sn : -cs;
  cosPhi = quadrant == 0u ? cs : quadrant == 1u ? -sn : quadrant == 2u ? -cs : sn;
}

// healpix::faceXYToVec.
dvec3 faceXYToVecD(uint face, double x, double y) {
  double z, phi, sth;
  faceXYToZPhiSin(face, x, y, z, phi, sth);
  precise double st = sth < -2.0 ? sqrt((1.0 - z) * (1.0 + z)) : sth;
  double sinPhi, cosPhi;
  sinCosD(phi, sinPhi, cosPhi);
  precise dvec3 v = dvec3(st * cosPhi, st * sinPhi, z);
  return v;
}
vec3 faceXYToVec(uint face, double x, double y) { return vec3(faceXYToVecD(face, x, y)); }

uint tsisStride() { return (1u << scene.tsisLevel) + 1u; }
double tsisAt(uint face, uint x, uint y) {
  uint stride = tsisStride();
  return scene.tsisSat.v[(face * stride + y) * stride + x];
}
// TsisTable::rect: the luminance summed over [x0, x1) x [y0, y1) of a face.
precise double tsisRect(uint face, uint x0, uint y0, uint x1, uint y1) {
  return tsisAt(face, x1, y1) - tsisAt(face, x0, y1) - tsisAt(face, x1, y0) + tsisAt(face, x0, y0);
}

// The regions of this invocation's shading point: GpuTsisSlot in memory.
uint gTsisBase;
uint gTsisCount;
double gTsisTotal;
#define tsisSlot(i) pc.tsisScratch.slots[gTsisBase + (i)]

// Arithmetic on the partition's arrays goes through these: `precise`
// variables fed from the global arrays make glslang's NoContraction
// propagation run out of memory.
precise double addD(double a, double b) { return a + b; }
precise double subD(double a, double b) { return a - b; }
precise double mulD(double a, double b) { return a * b; }
precise double divD(double a, double b) { return a / b; }
precise double tsisWeight(GpuTsisSlot r) { return r.energy > 0.0 ? r.energy * r.brdf : 0.0; }

struct TsisPeak {
  uint face, ix, iy;
  double value;
};

GpuTsisSlot tsisEvaluate(HpBrdf b, GpuMaterial m, TsisPeak peaks[2], double floorValue, uint face, uint x0, uint y0,
                        uint x1, uint y1) {
  GpuTsisSlot r;
  r.pad = 0u;
  r.cdf = 0.0;
  r.face = face;
  r.x0 = x0;
  r.y0 = y0;
  r.x1 = x1;
  r.y1 = y1;
  r.energy = tsisRect(face, x0, y0, x1, y1);
  precise double fn = double(1u << scene.tsisLevel);
  precise double xs[3] = double[3](double(x0) / fn, 0.5 * double(x0 + x1) / fn, double(x1) / fn);
  precise double ys[3] = double[3](double(y0) / fn, 0.5 * double(y0 + y1) / fn, double(y1) / fn);
  const uint px[5] = uint[5](1u, 0u, 2u, 0u, 2u);
  const uint py[5] = uint[5](1u, 0u, 0u, 2u, 2u);
  double lo = double(kInfinity), hi = 0.0;
  precise double sum = 0.0;
  uint count = 0u;
  for (uint i = 0u; i < 5u; ++i) {
    double v = double(hpBrdfValue(b, m, faceXYToVec(face, xs[px[i]], ys[py[i]])));
    lo = min(lo, v);
    hi = max(hi, v);
    sum += v;
    ++count;
  }
  for (uint i = 0u; i < 2u; ++i) {
    TsisPeak p = peaks[i];
    if (p.face == face && p.ix >= x0 && p.ix < x1 && p.iy >= y0 && p.iy < y1) {
      lo = min(lo, p.value);
      hi = max(hi, p.value);
      sum += p.value;
      ++count;
    }
  }
  precise double mean = sum / double(count) + floorValue;
  r.brdf = mean;
  bool splittable = x1 - x0 > 1u || y1 - y0 > 1u;
  precise double priority = r.energy * (hi - lo);
  r.priority = splittable ? priority : -1.0;
  return r;
}

// Stage 1 of TsisPoint: the BRDF-driven partition into the slots. One
// call of tsisEvaluate in one loop (the twelve faces, then both halves of
// each split, in the CPU's order): lavapipe compiles every inlined copy.
void tsisPartition(vec3 normalWorld, vec3 woWorld, GpuMaterial m) {
  HpBrdf b = makeHpBrdf(normalWorld, woWorld);
  precise double floorValue = double(1e-3) * double(hpBrdfScale(m));
  uint nside = 1u << scene.tsisLevel;
  TsisPeak peaks[2];
  vec3 peakDirs[2] = vec3[2](reflectAbout(b.wo, b.n), b.n);
  for (uint i = 0u; i < 2u; ++i) {
    uint pix = vecToPix(scene.tsisLevel, dvec3(peakDirs[i]));
    pixToXYF(scene.tsisLevel, pix, peaks[i].ix, peaks[i].iy, peaks[i].face);
    peaks[i].value = double(hpBrdfValue(b, m, normalize3(peakDirs[i])));
  }
  gTsisCount = 0u;
  uint best = 0u;
  GpuTsisSlot parent;
  for (uint step = 0u;; ++step) {
    uint face = step, x0 = 0u, y0 = 0u, x1 = nside, y1 = nside;
    bool second = step >= 12u && ((step - 12u) & 1u) == 1u;
    if (step >= 12u) {
      if (!second) {
        if (gTsisCount >= HT_TSIS_REGIONS) break;
        best = 0u;  // the first of the largest priorities, as std::max_element
        for (uint i = 1u; i < gTsisCount; ++i)
          if (tsisSlot(best).priority < tsisSlot(i).priority) best = i;
        if (!(tsisSlot(best).priority > 0.0)) break;
        parent = tsisSlot(best);
      }
      face = parent.face;
      x0 = parent.x0;
      y0 = parent.y0;
      x1 = parent.x1;
      y1 = parent.y1;
      if (x1 - x0 >= y1 - y0) {
        uint mid = (x0 + x1) / 2u;
        if (second) x0 = mid; else x1 = mid;
      } else {
        uint mid = (y0 + y1) / 2u;
        if (second) y0 = mid; else y1 = mid;
      }
    }
    GpuTsisSlot e = tsisEvaluate(b, m, peaks, floorValue, face, x0, y0, x1, y1);
    if (step >= 12u && !second) {
      tsisSlot(best) = e;
    } else {
      tsisSlot(gTsisCount) = e;
      ++gTsisCount;
    }
  }
  double total = 0.0;
  for (uint i = 0u; i < gTsisCount; ++i) {
    total = addD(total, tsisWeight(tsisSlot(i)));
    tsisSlot(i).cdf = total;
  }
  gTsisTotal = total;
  for (uint i = 0u; i < gTsisCount; ++i)
    tsisSlot(i).priority = total > 0.0 ? divD(tsisWeight(tsisSlot(i)), total) : 0.0;
}

// splitUnit (host/wis.cpp).
bool splitUnit(inout double u, double p) {
  bool first = u < p;
  precise double v = first ? u / p : (u - p) / (1.0 - p);
  u = clamp(v, 0.0, kBelowOneD);
  return first;
}

// TsisPoint::warp: the pixel, its direction and the solid-angle density (0: none).
double tsisWarp(double ux, double uy, out uint pixel, out vec3 dir) {
  pixel = 0u;
  dir = vec3(0.0, 1.0, 0.0);
  double target = mulD(ux, gTsisTotal);
  uint ri = 0u;  // std::upper_bound
  while (ri < gTsisCount && !(tsisSlot(ri).cdf > target)) ++ri;
  if (ri >= gTsisCount) ri = gTsisCount - 1u;
  while (!(tsisSlot(ri).priority > 0.0)) --ri;
  GpuTsisSlot r = tsisSlot(ri);
  double before = ri == 0u ? 0.0 : tsisSlot(ri - 1u).cdf;
  double u[2] = double[2](clamp(divD(subD(target, before), subD(r.cdf, before)), 0.0, kBelowOneD), uy);

  // d = 0: a column by the SAT's column sums; d = 1: a row inside that
  // column. cum(k) is the sum over the cells before k, and the cell taken
  // is the first k with cum(k) > target, minus one, stepped back over
  // empty cells.
  uint cell[2] = uint[2](r.x0, r.y0);
  for (uint d = 0u; d < 2u; ++d) {
    uint ax = d == 0u ? r.x0 : cell[0], bx = d == 0u ? r.x1 : cell[0] + 1u;
    uint first = d == 0u ? r.x0 : r.y0, lo = first + 1u, hi = d == 0u ? r.x1 : r.y1;
    double target = mulD(u[d], d == 0u ? r.energy : tsisRect(r.face, ax, r.y0, bx, r.y1));
    while (lo < hi) {
      uint mid = lo + (hi - lo) / 2u;
      if (tsisRect(r.face, ax, r.y0, d == 0u ? mid : bx, d == 0u ? r.y1 : mid) > target)
        hi = mid;
      else
        lo = mid + 1u;
    }
    uint k = lo - 1u;
    double c0 = tsisRect(r.face, ax, r.y0, d == 0u ? k : bx, d == 0u ? r.y1 : k);
    double c1 = tsisRect(r.face, ax, r.y0, d == 0u ? k + 1u : bx, d == 0u ? r.y1 : k + 1u);
    while (k > first && !(subD(c1, c0) > 0.0)) {
      --k;
      c1 = c0;
      c0 = tsisRect(r.face, ax, r.y0, d == 0u ? k : bx, d == 0u ? r.y1 : k);
    }
    cell[d] = k;
    u[d] = c1 > c0 ? clamp(divD(subD(target, c0), subD(c1, c0)), 0.0, kBelowOneD) : 0.5;
  }
  double x = u[0], y = u[1];

  uint level = scene.tsisLevel;
  uint node = xyfToPix(level, cell[0], cell[1], r.face);
  float value = treeAvg(levelOffset(level) + node);
  if (!(value > 0.0)) return 0.0;
  double prob = divD(mulD(r.priority, double(value)), r.energy);
  // Maps finer than the table: on down the average tree.
  for (; level < scene.envOrder; ++level) {
    uint first = levelOffset(level + 1u) + 4u * node;
    float w[4] = float[4](treeAvg(first), treeAvg(first + 1u), treeAvg(first + 2u), treeAvg(first + 3u));
    double sum = addD(addD(addD(double(w[0]), double(w[1])), double(w[2])), double(w[3]));
    uint c = splitUnit(x, divD(addD(double(w[0]), double(w[2])), sum)) ? 0u : 1u;
    uint rr = splitUnit(y, divD(double(w[c]), addD(double(w[c]), double(w[c + 2u])))) ? 0u : 1u;
    prob = mulD(prob, divD(double(w[c + 2u * rr]), sum));
    node = 4u * node + c + 2u * rr;
  }
  pixel = node;
  dir = envDirection(scene.envOrder, node, float(x), float(y));
  return divD(prob, envPixelSolidAngle());
}

// estimateTsis: `spp` points of the sampler through the
// two stages. tsisPrepare partitions the sphere (every dispatch: it draws
// nothing); false when there is nothing to sample.
bool tsisPrepare(Shading sh, vec3 normal, vec3 wo) {
  if (scene.envHasLight == 0u) return false;
  gTsisBase = (gl_GlobalInvocationID.y * pc.tileWidth + gl_GlobalInvocationID.x) * HT_TSIS_REGIONS;
  tsisPartition(normal, wo, sh.material);
  return gTsisTotal > 0.0;
}
// Samples [begin, end).
uint tsisSamples(Shading sh, uint begin, uint end, inout Sampler smp, inout dvec3 sum,
                 inout uint directions) {
  uint i = begin;
  for (; i < end; ++i) {
    samplerStart(smp, i);
    dvec2 u = samplerNext2DPrecise(smp);
    uint pixel;
    vec3 dir;
    double pdf = tsisWarp(u.x, u.y, pixel, dir);
    directions += 1u;
    if (!(pdf > 0.0)) continue;
    precise dvec3 est = dvec3(reflected(sh, dir, envRadiance(pixel))) / pdf;
    precise dvec3 total = sum + est;
    sum = total;
  }
  return i - begin;
}

// ---------------------------------------------------------------- wis

// The levels up to HT_WIS_EXACT_LEVELS of this invocation's product tree
// (WisPoint::top_, flat per-level layout) live in memory.
uint gWisBase;
uint gWisOrder, gWisExact;
double gWisTotal;
float gWisFloor;
HpBrdf gWisBrdf;
#define wisTop(i) pc.wisScratch.v[gWisBase + (i)]

// healpix::pixToVec(level, pix) at (dx, dy) inside the pixel, as the CPU's doubles.
dvec3 pixToVecD(uint level, uint pix, double dx, double dy) {
  uint ix, iy, face;
  pixToXYF(level, pix, ix, iy, face);
  precise double fn = double(1u << level);
  precise double x = (double(ix) + dx) / fn;
  precise double y = (double(iy) + dy) / fn;
  return faceXYToVecD(face, x, y);
}
// healpixNodeCenters: the centre of a node, HEALPix frame.
vec3 wisCenter(uint level, uint node) { return vec3(pixToVecD(level, node, 0.5lf, 0.5lf)); }
double wisPixelSolidAngle(uint level) { return divD(4.0lf * 3.14159265358979323846lf, double(12u << (2u * level))); }

double wisLeafWeight(GpuMaterial m, uint level, uint node) {
  float e = treeAvg(levelOffset(level) + node);
  if (!(e > 0.0)) return 0.0;
  return mulD(double(e), addD(double(hpBrdfValue(gWisBrdf, m, wisCenter(level, node))), double(gWisFloor)));
}
double wisChildWeight(GpuMaterial m, uint level, uint node, uint c) {
  return level + 1u <= gWisExact ? wisTop(levelOffset(level + 1u) + 4u * node + c)
                                 : wisLeafWeight(m, level + 1u, 4u * node + c);
}

// The WisPoint constructor: the exact levels, summed up from the deepest.
void wisBuild(vec3 normalWorld, vec3 woWorld, GpuMaterial m) {
  gWisBrdf = makeHpBrdf(normalWorld, woWorld);
  precise float floorValue = 1e-3 * hpBrdfScale(m);
  gWisFloor = floorValue;
  gWisOrder = min(pc.wisOrder, min(scene.envOrder, uint(HT_WIS_MAX_ORDER)));
  gWisExact = min(uint(HT_WIS_EXACT_LEVELS), gWisOrder);
  uint base = levelOffset(gWisExact);
  for (uint p = 0u; p < (12u << (2u * gWisExact)); ++p) wisTop(base + p) = wisLeafWeight(m, gWisExact, p);
  for (uint l = gWisExact; l > 0u; --l) {
    uint parent = levelOffset(l - 1u), child = levelOffset(l);
    for (uint p = 0u; p < (12u << (2u * (l - 1u))); ++p) {
      uint c = child + 4u * p;
      wisTop(parent + p) = addD(addD(addD(wisTop(c), wisTop(c + 1u)), wisTop(c + 2u)), wisTop(c + 3u));
    }
  }
  double total = 0.0;
  for (uint f = 0u; f < 12u; ++f) total = addD(total, wisTop(f));
  gWisTotal = total;
}

// WisPoint::warp: the solid-angle density (0: none).
double wisWarp(GpuMaterial m, double ux, double uy, out uint pixel, out double probability, out vec3 dir) {
  double target = mulD(ux, gWisTotal);
  double acc = 0.0;
  uint face = 0u;
  for (uint f = 0u; f < 12u; ++f) {
    double w = wisTop(f);
    if (!(w > 0.0)) continue;
    face = f;
    if (target < addD(acc, w)) break;
    acc = addD(acc, w);
  }
  double x = clamp(divD(subD(target, acc), wisTop(face)), 0.0, kBelowOneD);
  double y = uy;
  double prob = divD(wisTop(face), gWisTotal);
  uint node = face;
  for (uint level = 0u; level < gWisOrder; ++level) {
    double w[4];
    for (uint c = 0u; c < 4u; ++c) w[c] = wisChildWeight(m, level, node, c);
    double sum = addD(addD(addD(w[0], w[1]), w[2]), w[3]);
    uint col = splitUnit(x, divD(addD(w[0], w[2]), sum)) ? 0u : 1u;
    uint row = splitUnit(y, divD(w[col], addD(w[col], w[col + 2u]))) ? 0u : 1u;
    uint child = col + 2u * row;
    prob = mulD(prob, divD(w[child], sum));
    node = 4u * node + child;
  }
  pixel = node;
  probability = prob;
  dir = fromHealpixFrame(pixToVecD(gWisOrder, node, x, y));
  return divD(prob, wisPixelSolidAngle(gWisOrder));
}

// WisPoint::approximateProduct: the leaf's average radiance x f cos at its centre.
vec3 wisApproximateProduct(GpuMaterial m, uint pixel) {
  uint count = 1u << (2u * (scene.envOrder - gWisOrder));
  precise dvec3 sum = dvec3(0.0);
  for (uint p = pixel * count; p < (pixel + 1u) * count; ++p) sum += dvec3(envRadiance(p));
  precise dvec3 mean = sum / double(count);
  vec3 average = vec3(mean);
  if (average == vec3(0.0)) return average;
  precise vec3 product = average * evalBsdf(m, gWisBrdf.woLocal, toLocal(gWisBrdf.frame, wisCenter(gWisOrder, pixel)));
  return product;
}

// estimateWis: `spp` points of the sampler warped down the
// product tree; wis-biased returns the approximated product instead of f.
// wisPrepare builds the tree (every dispatch: it draws nothing); false when
// there is nothing to sample.
bool wisPrepare(Shading sh, vec3 normal, vec3 wo) {
  if (scene.envHasLight == 0u) return false;
  gWisBase = (gl_GlobalInvocationID.y * pc.tileWidth + gl_GlobalInvocationID.x) * HT_WIS_TOP_NODES;
  wisBuild(normal, wo, sh.material);
  return gWisTotal > 0.0;
}
// Samples [begin, end).
uint wisSamples(Shading sh, uint begin, uint end, inout Sampler smp, bool biased, inout dvec3 sum,
                inout uint directions) {
  double pixelSolidAngle = wisPixelSolidAngle(gWisOrder);
  uint i = begin;
  for (; i < end; ++i) {
    samplerStart(smp, i);
    dvec2 u = samplerNext2DPrecise(smp);
    uint pixel;
    double probability;
    vec3 dir;
    double pdf = wisWarp(sh.material, u.x, u.y, pixel, probability, dir);
    directions += 1u;
    if (!(probability > 0.0)) continue;
    precise dvec3 value;
    if (biased) {
      vec3 product = wisApproximateProduct(sh.material, pixel);
      if (product == vec3(0.0)) continue;
      value = dvec3(product) * divD(pixelSolidAngle, probability);
    } else {
      vec3 radiance = envEval(dir);
      if (radiance == vec3(0.0)) continue;
      precise vec3 fcos = evalBsdf(sh.material, sh.woLocal, toLocal(sh.frame, dir));
      if (fcos == vec3(0.0)) continue;
      precise vec3 product = radiance * fcos;
      value = dvec3(product) / pdf;
    }
    ++gShadowRays;
    if (!occluded(sh.origin, dir)) {
      precise dvec3 total = sum + value;
      sum = total;
    }
  }
  return i - begin;
}

#else
bool wisPrepare(Shading sh, vec3 normal, vec3 wo) { return false; }
uint wisSamples(Shading sh, uint begin, uint end, inout Sampler smp, bool biased, inout accvec3 sum,
                inout uint directions) {
  return end - begin;
}
bool tsisPrepare(Shading sh, vec3 normal, vec3 wo) { return false; }
uint tsisSamples(Shading sh, uint begin, uint end, inout Sampler smp, inout accvec3 sum,
                 inout uint directions) {
  return end - begin;
}
#endif

#endif
