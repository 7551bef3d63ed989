// One source of truth for the host and the shaders: push constants, buffer
// structs, binding indices and the workgroup size. Included by C++ (with glm
// types, checked by static_assert) and by GLSL (GL_EXT_scalar_block_layout,
// so every struct maps one to one onto the host's arrays).
//
// Large per-scene arrays (environment radiance, the max/avg trees and, for
// the HT methods, the per-node HEALPix geometry) keep the CPU's flat
// per-level layout (host/tree.h) and are split into chunks of at most
// 96 MiB, each its own VkBuffer; the shaders reach them through buffer device
// addresses held in GpuScene, so no descriptor limit or 128 MiB storage
// buffer range caps the environment's resolution.
#ifndef HT_SHADERS_COMMON_H
#define HT_SHADERS_COMMON_H

#define HT_WORKGROUP_SIZE 8  // 8x8 invocations; lavapipe needs a width that is a multiple of 8

#define HT_BINDING_SCENE 0      // GpuScene
#define HT_BINDING_MATERIALS 1  // GpuMaterial[]
#define HT_BINDING_SPHERES 2    // GpuSphere[]
#define HT_BINDING_PLANES 3     // GpuPlane[]
#define HT_BINDING_PIXELS 4     // GpuPixel[] of the current tile (written)
#define HT_BINDING_COUNT 5

// Chunked arrays: element i lives in chunk i >> SHIFT at i & (2^SHIFT - 1).
#define HT_MAX_CHUNKS 128
#define HT_RADIANCE_CHUNK_SHIFT 23  // vec3: 96 MiB per chunk
#define HT_TREE_CHUNK_SHIFT 24      // float: 64 MiB per chunk
#define HT_HT_VEC3_CHUNK_SHIFT 23   // HT node centres (vec3): 96 MiB
#define HT_HT_VEC2_CHUNK_SHIFT 23   // HT node cos/sin radius (vec2): 64 MiB

// Method numbers: the values of ht::Method (host/integrator.h).
#define HT_METHOD_UNIFORM 0
#define HT_METHOD_COSINE 1
#define HT_METHOD_ENV 2
#define HT_METHOD_BRDF 3
#define HT_METHOD_MIS 4
#define HT_METHOD_HT 5
#define HT_METHOD_HT_VIS 6
#define HT_METHOD_HT_BIASED 7
#define HT_METHOD_HT_VIS_BIASED 8

#define HT_MATERIAL_LAMBERT 0
#define HT_MATERIAL_PHONG 1
#define HT_MATERIAL_GGX 2

#ifdef __cplusplus
#include <cstddef>
#include <cstdint>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace ht::gpu {
using uint = uint32_t;
using vec2 = glm::vec2;
using vec3 = glm::vec3;
using uvec2 = glm::uvec2;
#define HT_CHUNK_REF(type) uint64_t  // VkDeviceAddress of one chunk, 0 if absent
#else
layout(buffer_reference, scalar, buffer_reference_align = 4) readonly buffer Vec3Chunk { vec3 v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 4) readonly buffer Vec2Chunk { vec2 v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 4) readonly buffer FloatChunk { float v[]; };
#define HT_CHUNK_REF(type) type
#endif

// Per scene, uploaded once.
struct GpuScene {
  // Device addresses first: 8-byte aligned.
  HT_CHUNK_REF(Vec3Chunk) radiance[HT_MAX_CHUNKS];   // Environment::radiance
  HT_CHUNK_REF(FloatChunk) treeAvg[HT_MAX_CHUNKS];   // MaxAvgTree::avgv
  HT_CHUNK_REF(FloatChunk) treeMax[HT_MAX_CHUNKS];   // MaxAvgTree::maxv
  // HT stage (host/ht.h HtGeometry, same node layout as the trees); unused
  // (0) by the baseline methods.
  HT_CHUNK_REF(Vec3Chunk) htCenters[HT_MAX_CHUNKS];
  HT_CHUNK_REF(Vec2Chunk) htCosSinRadius[HT_MAX_CHUNKS];
  float htLevelRadius[32];

  // Camera basis, computed on the host exactly as cameraRay (host/scene.cpp) does.
  vec3 camPosition;
  float tanHalfFov;
  vec3 camW;
  float reserved0;
  vec3 camU;
  uint envOrder;      // Nside = 2^envOrder
  vec3 camV;
  uint envHasLight;   // 0: all-black map, nothing to sample
  float envCosYaw;
  float envSinYaw;
  uvec2 envPixelSolidAngleBits;  // double: 4 pi / (12 4^order), as (low, high) words
  float envPixelSolidAngle;      // the same in single precision (shaders without fp64)
  uint sphereCount;
  uint planeCount;
  uint materialCount;
};

struct GpuMaterial {
  uint type;          // HT_MATERIAL_*
  vec3 diffuse;
  vec3 specular;
  float exponent;
  float alpha;
  float specularProbability;  // specularLobeProbability(), computed on the host
};

struct GpuSphere {
  vec3 center;
  float radius;
  uint material;
};

struct GpuPlane {
  vec3 point;
  vec3 normal;
  uint material;
};

// One output pixel of a tile.
struct GpuPixel {
  vec3 radiance;
  uint shaded;      // 1: a surface was hit and shaded, 0: the ray escaped
  uint directions;  // directions drawn
  uint shadowRays;
  uint htNodes;     // HT nodes visited (HT stage)
  uint reserved;
};

// Per dispatch (at most 128 bytes on lavapipe).
struct GpuPush {
  uint width;   // whole image
  uint height;
  uint tileX;   // tile origin and size, pixels
  uint tileY;
  uint tileWidth;
  uint tileHeight;
  uint method;  // HT_METHOD_*
  uint spp;
  uint seed;
  uint reserved[7];  // room for the HT stage's per-dispatch settings
};

#ifdef __cplusplus
static_assert(sizeof(GpuScene) == 5 * 8 * HT_MAX_CHUNKS + 4 * 32 + 96);
static_assert(offsetof(GpuScene, treeAvg) == 8 * HT_MAX_CHUNKS);
static_assert(offsetof(GpuScene, htLevelRadius) == 5 * 8 * HT_MAX_CHUNKS);
static_assert(offsetof(GpuScene, camPosition) == 5 * 8 * HT_MAX_CHUNKS + 4 * 32);
static_assert(offsetof(GpuScene, envPixelSolidAngleBits) - offsetof(GpuScene, camPosition) == 72);
static_assert(offsetof(GpuScene, materialCount) - offsetof(GpuScene, camPosition) == 92);
static_assert(sizeof(GpuMaterial) == 40 && offsetof(GpuMaterial, diffuse) == 4 &&
              offsetof(GpuMaterial, specular) == 16 && offsetof(GpuMaterial, specularProbability) == 36);
static_assert(sizeof(GpuSphere) == 20 && offsetof(GpuSphere, radius) == 12 && offsetof(GpuSphere, material) == 16);
static_assert(sizeof(GpuPlane) == 28 && offsetof(GpuPlane, normal) == 12 && offsetof(GpuPlane, material) == 24);
static_assert(sizeof(GpuPixel) == 32 && offsetof(GpuPixel, shaded) == 12 && offsetof(GpuPixel, htNodes) == 24);
static_assert(sizeof(GpuPush) == 64 && offsetof(GpuPush, seed) == 32);
static_assert(sizeof(vec3) == 12 && alignof(vec3) == 4 && sizeof(vec2) == 8);

inline constexpr uint32_t kWorkgroupSize = HT_WORKGROUP_SIZE;
inline constexpr uint64_t kRadianceChunkElements = uint64_t(1) << HT_RADIANCE_CHUNK_SHIFT;
inline constexpr uint64_t kTreeChunkElements = uint64_t(1) << HT_TREE_CHUNK_SHIFT;
}  // namespace ht::gpu
#undef HT_CHUNK_REF
#endif

#endif  // HT_SHADERS_COMMON_H
