// Test kernel: the shaders' HEALPix next to host/healpix.cpp (tests/test_gpu.cpp).
// Per item: direction -> nested pixel, and (pixel, dx, dy) -> direction.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_scalar_block_layout : require

#include "healpix.glsl"

layout(local_size_x = 64) in;

struct HealpixTestItem {
  vec3 dir;    // in: direction (HEALPix frame)
  uint pixel;  // in: pixel for pixToVec
  float dx, dy;
};
layout(set = 0, binding = 0, scalar) readonly buffer Items { HealpixTestItem items[]; };
layout(set = 0, binding = 1, scalar) writeonly buffer Pixels { uint pixels[]; };
layout(set = 0, binding = 2, scalar) writeonly buffer Dirs { vec3 dirs[]; };
layout(push_constant, scalar) uniform Push {
  uint order;
  uint count;
} pc;

void main() {
  uint i = gl_GlobalInvocationID.x;
  if (i >= pc.count) return;
  HealpixTestItem it = items[i];
  pixels[i] = vecToPix(pc.order, hvec3(it.dir));
  dirs[i] = vec3(pixToVec(pc.order, it.pixel, it.dx, it.dy));
}
