// Tabulated BRDF bounds of the ht* methods (host/brdf_table.cpp), read from
// GpuScene::htBrdfTables: per material, the averages then the max pyramid,
// each per outgoing-elevation bin (BrdfTable's layout, levels back to back).
#ifndef HT_HT_TABLE_GLSL
#define HT_HT_TABLE_GLSL

#include "bindings.glsl"
#include "healpix.glsl"
#include "math.glsl"

#define kHtHalfPi uintBitsToFloat(0x3FC90FDBu)  // 0.5f * kPi
#define kHtTangentEpsilon uintBitsToFloat(0x358637BDu)  // 1e-6f

// atan2, acos and asin in double where the device has it (healpix.glsl's
// atan2d), rounded to float: the driver's float versions are too coarse to
// pick the CPU's cells and interpolation weights.
#if HT_FP64
float htAtan2(float y, float x) { return float(atan2d(double(y), double(x))); }
float htAcos(float z) {
  precise double s = sqrt((1.0lf - double(z)) * (1.0lf + double(z)));
  return float(atan2d(s, double(z)));
}
float htAsin(float z) {
  precise double c = sqrt((1.0lf - double(z)) * (1.0lf + double(z)));
  return float(atan2d(double(z), c));
}
#else
float htAtan2(float y, float x) { return atan(y, x); }
float htAcos(float z) { return acos(z); }
float htAsin(float z) { return asin(z); }
#endif

// One shading point's view of its material's table.
struct HtTableFrame {
  uint offset;  // the material's table
  uint bin;     // outgoing elevation bin
  vec3 x, y;    // tangent frame (x towards wo), the table's azimuth 0
};

float htTable(HtTableFrame f, uint i) { return scene.htBrdfTables.v[f.offset + i]; }

// BrdfTable::maxAt.
float htTableMax(HtTableFrame f, uint level, int it, int ip) {
  int t = HT_BRDF_TABLE_THETA >> level, p = HT_BRDF_TABLE_PHI >> level;
  uint offset = uint(HT_BRDF_TABLE_CELLS);  // the averages come first
  for (uint l = 0u; l < level; ++l)
    offset += uint(HT_BRDF_TABLE_THETA_O * (HT_BRDF_TABLE_THETA >> l) * (HT_BRDF_TABLE_PHI >> l));
  return htTable(f, offset + uint((int(f.bin) * t + clamp(it, 0, t - 1)) * p + clamp(ip, 0, p - 1)));
}

// `fallbackX`: the tangent to use where wo is along the normal.
HtTableFrame htTableFrame(uint material, vec3 woLocal, vec3 wo, vec3 n, vec3 fallbackX) {
  HtTableFrame f;
  f.offset = material * uint(HT_BRDF_TABLE_FLOATS);
  float thetaO = htAcos(clamp(woLocal.z, -1.0, 1.0));
  precise float x = thetaO / kHtHalfPi * float(HT_BRDF_TABLE_THETA_O);
  f.bin = uint(clamp(int(x), 0, HT_BRDF_TABLE_THETA_O - 1));
  precise vec3 tangent = wo - dot3(wo, n) * n;
  f.x = length3(tangent) > kHtTangentEpsilon ? normalize3(tangent) : fallbackX;
  f.y = cross3(n, f.x);
  return f;
}

// BrdfTable::bound.
precise float htTableBound(HtTableFrame f, vec3 wi, float cosRadius, float sinRadius) {
  precise float dTheta = kHtHalfPi / float(HT_BRDF_TABLE_THETA);
  precise float dPhi = kPi / float(HT_BRDF_TABLE_PHI);
  float radius = htAtan2(sinRadius, cosRadius);
  float theta = htAcos(clamp(wi.z, -1.0, 1.0));
  precise float lowest = theta - radius;
  if (lowest >= kHtHalfPi) return 0.0;
  precise float highest = theta + radius;
  float t0 = max(0.0, lowest), t1 = min(kHtHalfPi, highest);
  float p0 = 0.0, p1 = kPi;
  float sinTheta = sin(theta);
  if (radius < theta && sinRadius < sinTheta) {
    float phi = abs(htAtan2(wi.y, wi.x));
    precise float ratio = sinRadius / sinTheta;
    float half_ = htAsin(ratio);
    precise float a = phi - half_;
    precise float b = phi + half_;
    precise float twoPi = 2.0 * kPi;
    precise float wrapped = twoPi - b;
    p0 = a < 0.0 ? 0.0 : (b > kPi ? min(a, wrapped) : a);
    p1 = b > kPi ? kPi : (a < 0.0 ? max(b, -a) : b);
  }
  precise float q0 = t0 / dTheta, q1 = t1 / dTheta, r0 = p0 / dPhi, r1 = p1 / dPhi;
  int i0 = int(q0), i1 = min(HT_BRDF_TABLE_THETA - 1, int(q1));
  int j0 = int(r0), j1 = min(HT_BRDF_TABLE_PHI - 1, int(r1));
  uint level = 0u;
  while (level + 1u < uint(HT_BRDF_TABLE_LEVELS) &&
         ((i1 >> level) - (i0 >> level) > 1 || (j1 >> level) - (j0 >> level) > 1))
    ++level;
  float m = 0.0;
  for (int i = i0 >> level; i <= i1 >> level; ++i)
    for (int j = j0 >> level; j <= j1 >> level; ++j) m = max(m, htTableMax(f, level, i, j));
  return m;
}

// BrdfTable::average.
precise float htTableAverage(HtTableFrame f, vec3 wi) {
  if (wi.z <= 0.0) return 0.0;
  precise float dTheta = kHtHalfPi / float(HT_BRDF_TABLE_THETA);
  precise float dPhi = kPi / float(HT_BRDF_TABLE_PHI);
  precise float x = htAcos(min(1.0, wi.z)) / dTheta - 0.5;
  precise float y = abs(htAtan2(wi.y, wi.x)) / dPhi - 0.5;
  int i = int(floor(x)), j = int(floor(y));
  precise float fx = x - float(i);
  precise float fy = y - float(j);
  uint base = f.bin * uint(HT_BRDF_TABLE_THETA);
  int ia = clamp(i, 0, HT_BRDF_TABLE_THETA - 1), ib = clamp(i + 1, 0, HT_BRDF_TABLE_THETA - 1);
  int ja = clamp(j, 0, HT_BRDF_TABLE_PHI - 1), jb = clamp(j + 1, 0, HT_BRDF_TABLE_PHI - 1);
  float a00 = htTable(f, (base + uint(ia)) * uint(HT_BRDF_TABLE_PHI) + uint(ja));
  float a01 = htTable(f, (base + uint(ia)) * uint(HT_BRDF_TABLE_PHI) + uint(jb));
  float a10 = htTable(f, (base + uint(ib)) * uint(HT_BRDF_TABLE_PHI) + uint(ja));
  float a11 = htTable(f, (base + uint(ib)) * uint(HT_BRDF_TABLE_PHI) + uint(jb));
  return (1.0 - fx) * ((1.0 - fy) * a00 + fy * a01) + fx * ((1.0 - fy) * a10 + fy * a11);
}

#endif
