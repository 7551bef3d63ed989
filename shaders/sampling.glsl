// host/sampling.h in GLSL: warps paired with their densities. Local frames
// have the normal along +z. cos, sin and pow are the device's (within an ulp
// or two of libm's), everything else rounds as on the CPU.
#ifndef HT_SAMPLING_GLSL
#define HT_SAMPLING_GLSL

#include "math.glsl"

// Orthonormal basis around a unit normal (Duff et al., JCGT 2017).
struct Frame {
  vec3 s, t, n;
};
Frame makeFrame(vec3 n) {
  Frame f;
  precise float sign = copySign(1.0, n.z);
  precise float a = -1.0 / (sign + n.z);
  precise float b = n.x * n.y * a;
  precise vec3 s = vec3(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
  precise vec3 t = vec3(b, sign + n.y * n.y * a, -n.y);
  f.s = s;
  f.t = t;
  f.n = n;
  return f;
}
precise vec3 toLocal(Frame f, vec3 v) { return vec3(dot3(v, f.s), dot3(v, f.t), dot3(v, f.n)); }
precise vec3 toWorld(Frame f, vec3 v) { return v.x * f.s + v.y * f.t + v.z * f.n; }

precise vec3 sampleUniformSphere(vec2 u) {
  precise float z = 1.0 - 2.0 * u.x;
  precise float r = sqrt(max(0.0, 1.0 - z * z));
  precise float phi = 2.0 * kPi * u.y;
  return vec3(r * cos(phi), r * sin(phi), z);
}
precise float uniformSpherePdf() { return 0.25 * kInvPi; }

precise vec3 sampleCosineHemisphere(vec2 u) {
  precise float r = sqrt(u.x);
  precise float phi = 2.0 * kPi * u.y;
  return vec3(r * cos(phi), r * sin(phi), sqrt(max(0.0, 1.0 - u.x)));
}
precise float cosineHemispherePdf(float cosTheta) { return max(0.0, cosTheta) * kInvPi; }

// Density proportional to cos^n around +z over the whole sphere.
precise vec3 samplePowerCosine(vec2 u, float exponent) {
  precise float z = pow(1.0 - u.x, 1.0 / (exponent + 1.0));
  precise float r = sqrt(max(0.0, 1.0 - z * z));
  precise float phi = 2.0 * kPi * u.y;
  return vec3(r * cos(phi), r * sin(phi), z);
}
precise float powerCosinePdf(float cosTheta, float exponent) {
  return cosTheta > 0.0 ? (exponent + 1.0) * 0.5 * kInvPi * pow(cosTheta, exponent) : 0.0;
}

// GGX (Trowbridge-Reitz), isotropic roughness alpha.
precise float ggxD(vec3 h, float alpha) {
  if (h.z <= 0.0) return 0.0;
  precise float a2 = alpha * alpha;
  precise float d = h.z * h.z * (a2 - 1.0) + 1.0;
  return a2 / (kPi * d * d);
}
precise float ggxLambda(vec3 w, float alpha) {
  precise float z2 = w.z * w.z;
  if (z2 <= 0.0) return 0.0;
  precise float tan2 = max(0.0, 1.0 - z2) / z2;
  return 0.5 * (sqrt(1.0 + alpha * alpha * tan2) - 1.0);
}
precise float ggxG1(vec3 w, float alpha) { return 1.0 / (1.0 + ggxLambda(w, alpha)); }

// Visible-normal sampling (Heitz, JCGT 2018).
precise vec3 sampleGgxVisibleNormal(vec3 wo, float alpha, vec2 u) {
  precise vec3 vh = normalize3(vec3(alpha * wo.x, alpha * wo.y, wo.z));
  precise float lensq = vh.x * vh.x + vh.y * vh.y;
  precise vec3 t1 = lensq > 0.0 ? vec3(-vh.y, vh.x, 0.0) / sqrt(lensq) : vec3(1.0, 0.0, 0.0);
  precise vec3 t2 = cross3(vh, t1);
  precise float r = sqrt(u.x);
  precise float phi = 2.0 * kPi * u.y;
  precise float p1 = r * cos(phi);
  precise float p2 = r * sin(phi);
  precise float s = 0.5 * (1.0 + vh.z);
  p2 = (1.0 - s) * sqrt(max(0.0, 1.0 - p1 * p1)) + s * p2;
  precise vec3 nh = p1 * t1 + p2 * t2 + sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2)) * vh;
  return normalize3(vec3(alpha * nh.x, alpha * nh.y, max(1e-7, nh.z)));
}
// Density of the reflected direction wi when h is drawn by the routine above.
precise float ggxReflectionPdf(vec3 wo, vec3 wi, float alpha) {
  if (wo.z <= 0.0) return 0.0;
  precise vec3 hv = wo + wi;
  precise float len = length3(hv);
  if (len == 0.0) return 0.0;
  precise vec3 h = hv / len;
  if (h.z <= 0.0 || dot3(wo, h) <= 0.0) return 0.0;
  return ggxD(h, alpha) * ggxG1(wo, alpha) / (4.0 * wo.z);
}

precise vec3 reflectAbout(vec3 w, vec3 n) { return 2.0 * dot3(w, n) * n - w; }

#endif
