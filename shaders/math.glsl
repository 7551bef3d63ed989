// Arithmetic that must reproduce the CPU reference: every result is
// `precise` (no contraction into fma, no reassociation) and the vector
// helpers evaluate in glm's order, so that add, mul, div and sqrt round
// exactly as in the C++ build (-ffp-contract=off). GLSL's own dot, length,
// normalize and cross may be evaluated in another order: not used.
#ifndef HT_MATH_GLSL
#define HT_MATH_GLSL

const float kPi = 3.14159265358979323846;            // rounds to 0x40490FDB, as ht::kPi
#define kInvPi uintBitsToFloat(0x3EA2F983u)   // ht::kInvPi = 1.0f / kPi in float
#define kInfinity uintBitsToFloat(0x7F800000u)

precise float dot3(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
precise float length3(vec3 v) { return sqrt(dot3(v, v)); }
// glm::normalize: v * (1 / sqrt(dot(v, v))).
precise vec3 normalize3(vec3 v) {
  precise float inv = 1.0 / sqrt(dot3(v, v));
  return v * inv;
}
precise vec3 cross3(vec3 x, vec3 y) {
  return vec3(x.y * y.z - y.y * x.z, x.z * y.x - y.z * x.x, x.x * y.y - y.x * x.y);
}
// ht::luminance, with the C++ float constants by their bits (a GLSL literal
// may round twice).
precise float luminance(vec3 c) {
  return uintBitsToFloat(0x3E59B3D0u) * c.r + uintBitsToFloat(0x3F371759u) * c.g + uintBitsToFloat(0x3D93DD98u) * c.b;
}
// std::copysign(magnitude, sign), signed zeros included.
float copySign(float magnitude, float sign) {
  return uintBitsToFloat((floatBitsToUint(magnitude) & 0x7FFFFFFFu) | (floatBitsToUint(sign) & 0x80000000u));
}

#endif
