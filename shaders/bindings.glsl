// The descriptor set and push constants of the render shaders (common.h).
#ifndef HT_BINDINGS_GLSL
#define HT_BINDINGS_GLSL

#include "common.h"

layout(set = 0, binding = HT_BINDING_SCENE, scalar) readonly buffer SceneBuffer { GpuScene scene; };
layout(set = 0, binding = HT_BINDING_MATERIALS, scalar) readonly buffer MaterialBuffer { GpuMaterial materials[]; };
layout(set = 0, binding = HT_BINDING_SPHERES, scalar) readonly buffer SphereBuffer { GpuSphere spheres[]; };
layout(set = 0, binding = HT_BINDING_PLANES, scalar) readonly buffer PlaneBuffer { GpuPlane planes[]; };
layout(set = 0, binding = HT_BINDING_PIXELS, scalar) writeonly buffer PixelBuffer { GpuPixel pixels[]; };
layout(push_constant, scalar) uniform PushBlock { GpuPush pc; };

#endif
