// The descriptor set and push constants of the render shaders (common.h).
#ifndef HT_BINDINGS_GLSL
#define HT_BINDINGS_GLSL

#include "common.h"

layout(set = 0, binding = HT_BINDING_SCENE, scalar) uniform SceneBuffer { GpuScene scene; };
layout(set = 0, binding = HT_BINDING_MATERIALS, scalar) readonly buffer MaterialBuffer { GpuMaterial materials[]; };
layout(set = 0, binding = HT_BINDING_SPHERES, scalar) readonly buffer SphereBuffer { GpuSphere spheres[]; };
layout(set = 0, binding = HT_BINDING_PLANES, scalar) readonly buffer PlaneBuffer { GpuPlane planes[]; };
layout(set = 0, binding = HT_BINDING_BVH_NODES, scalar) readonly buffer BvhNodeBuffer { GpuBvhNode bvhNodes[]; };
layout(set = 0, binding = HT_BINDING_BVH_ORDER, scalar) readonly buffer BvhOrderBuffer { uint bvhOrder[]; };
layout(set = 0, binding = HT_BINDING_PIXELS, scalar) writeonly buffer PixelBuffer { GpuPixel pixels[]; };
layout(push_constant, scalar) uniform PushBlock { GpuPush pc; };
// The method as a specialization constant (HT_METHOD_*; HT_METHOD_ANY: the
// push constant's): lavapipe compiles every branch of a shader, so each
// method gets a pipeline that holds its own code only.
layout(constant_id = HT_SPEC_METHOD) const uint kSpecializedMethod = HT_METHOD_ANY;
// The large arrays through their texel views (true) or their chunks' device
// addresses (false), chosen per scene by the host.
layout(constant_id = HT_SPEC_TEXELS) const bool kTexels = false;
// The scene's spheres and planes (at most HT_MAX_CAPS), one cap slot each:
// loops over the caps have a constant count, so that the driver can unroll
// them and read each cap's arrays at a constant index (llvmpipe reads an
// array at a loop counter lane by lane).
layout(constant_id = HT_SPEC_CAP_SLOTS) const uint kCapSlots = HT_MAX_CAPS;
// HT's tabulated BRDF bounds (HT_FLAG_BRDF_TABLE) can be on: false leaves
// their code out of the pipeline (llvmpipe runs every branch).
layout(constant_id = HT_SPEC_BRDF_TABLE) const bool kBrdfTable = true;
layout(set = 0, binding = HT_BINDING_RADIANCE_TEXELS) uniform samplerBuffer radianceTexels;
layout(set = 0, binding = HT_BINDING_TREE_AVG_TEXELS) uniform samplerBuffer treeAvgTexels;
layout(set = 0, binding = HT_BINDING_TREE_MAX_TEXELS) uniform samplerBuffer treeMaxTexels;
layout(set = 0, binding = HT_BINDING_HT_CENTERS_TEXELS) uniform samplerBuffer htCentersTexels;
layout(set = 0, binding = HT_BINDING_HT_CONES_TEXELS) uniform samplerBuffer htConesTexels;
layout(set = 0, binding = HT_BINDING_FRONTIER_CHROMA_TEXELS) uniform samplerBuffer frontierChromaTexels;
layout(set = 0, binding = HT_BINDING_FRONTIER_CENTROID_TEXELS) uniform samplerBuffer frontierCentroidTexels;
layout(set = 0, binding = HT_BINDING_FRONTIER_BINS_TEXELS) uniform usamplerBuffer frontierBinsTexels;
layout(set = 0, binding = HT_BINDING_CUT_TREE_TEXELS) uniform samplerBuffer cutTreeTexels;
layout(set = 0, binding = HT_BINDING_CUT_RECORD_TEXELS) uniform samplerBuffer cutRecordTexels;
layout(set = 0, binding = HT_BINDING_CUT_LOOKUP_TEXELS) uniform usamplerBuffer cutLookupTexels;
layout(set = 0, binding = HT_BINDING_SPHERE_TEXELS) uniform samplerBuffer sphereTexels;
layout(set = 0, binding = HT_BINDING_BVH_NODE_TEXELS) uniform usamplerBuffer bvhNodeTexels;
layout(set = 0, binding = HT_BINDING_BVH_ORDER_TEXELS) uniform usamplerBuffer bvhOrderTexels;

// Element i of a texel view of vec3s or vec2s stored as floats.
vec3 texelVec3(samplerBuffer b, uint i) {
  int t = 3 * int(i);
  return vec3(texelFetch(b, t).x, texelFetch(b, t + 1).x, texelFetch(b, t + 2).x);
}
vec2 texelVec2(samplerBuffer b, uint i) {
  int t = 2 * int(i);
  return vec2(texelFetch(b, t).x, texelFetch(b, t + 1).x);
}

// Sphere i's centre and radius (its material only from `spheres`), BVH node
// i, and the BVH's k-th sphere index.
GpuSphere sphereShape(uint i) {
  if (!kTexels) return spheres[i];
  vec4 v = texelFetch(sphereTexels, int(i));
  return GpuSphere(v.xyz, v.w, 0u);
}
GpuBvhNode bvhNode(uint i) {
  if (!kTexels) return bvhNodes[i];
  uvec4 a = texelFetch(bvhNodeTexels, int(2u * i)), b = texelFetch(bvhNodeTexels, int(2u * i + 1u));
  return GpuBvhNode(uintBitsToFloat(a.xyz), a.w, uintBitsToFloat(b.xyz), b.w);
}
uint bvhSphere(uint k) { return kTexels ? texelFetch(bvhOrderTexels, int(k)).x : bvhOrder[k]; }

#endif
