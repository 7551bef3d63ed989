// host/bsdf.cpp in GLSL: diffuse lobe plus an optional Phong or GGX lobe,
// f * cos in the local shading frame.
#ifndef HT_BSDF_GLSL
#define HT_BSDF_GLSL

#include "common.h"
#include "sampling.glsl"

precise vec3 schlickFresnel(vec3 f0, float cosTheta) {
  precise float m = 1.0 - clamp(cosTheta, 0.0, 1.0);
  precise float m5 = m * m * m * m * m;
  return f0 + (vec3(1.0) - f0) * m5;
}

vec3 mirrorDir(vec3 wo) { return vec3(-wo.x, -wo.y, wo.z); }

precise vec3 evalBsdf(GpuMaterial m, vec3 wo, vec3 wi) {
  if (wo.z <= 0.0 || wi.z <= 0.0) return vec3(0.0);
  precise vec3 result = m.diffuse * (kInvPi * wi.z);
  if (m.type == HT_MATERIAL_PHONG) {
    precise float c = dot3(mirrorDir(wo), wi);
    if (c > 0.0) result += m.specular * ((m.exponent + 2.0) * 0.5 * kInvPi * pow(c, m.exponent) * wi.z);
  } else if (m.type == HT_MATERIAL_GGX) {
    precise vec3 h = normalize3(wo + wi);
    precise float d = ggxD(h, m.alpha);
    precise float g = 1.0 / (1.0 + ggxLambda(wo, m.alpha) + ggxLambda(wi, m.alpha));
    result += schlickFresnel(m.specular, dot3(wi, h)) * (d * g / (4.0 * wo.z));
  }
  return result;
}

// sampleBsdf (host/bsdf.cpp): u.x chooses the lobe, then drives it with u.y.
precise vec3 sampleBsdf(GpuMaterial m, vec3 wo, vec2 u) {
  float ps = m.specularProbability;
  bool diffuse = u.x >= ps;
  precise float x = diffuse ? (u.x - ps) / (1.0 - ps) : u.x / ps;
  vec2 uv = vec2(min(x, uintBitsToFloat(0x3f7fffffu)), u.y);
  if (diffuse) return sampleCosineHemisphere(uv);
  if (m.type == HT_MATERIAL_PHONG) return toWorld(makeFrame(mirrorDir(wo)), samplePowerCosine(uv, m.exponent));
  return reflectAbout(wo, sampleGgxVisibleNormal(wo, m.alpha, uv));
}

precise float bsdfPdf(GpuMaterial m, vec3 wo, vec3 wi) {
  float ps = m.specularProbability;
  precise float pdf = (1.0 - ps) * cosineHemispherePdf(wi.z);
  if (ps > 0.0) {
    if (m.type == HT_MATERIAL_PHONG)
      pdf += ps * powerCosinePdf(dot3(mirrorDir(wo), wi), m.exponent);
    else
      pdf += ps * ggxReflectionPdf(wo, wi, m.alpha);
  }
  return pdf;
}

#endif
