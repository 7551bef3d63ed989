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
// Where every large array fits in its first chunk and in a texel buffer
// view (kTexels), the shaders read that chunk as floats of a uniform texel
// buffer: lavapipe gathers those for all lanes at once, where it loads
// through a device address lane by lane.
#define HT_BINDING_RADIANCE_TEXELS 5
#define HT_BINDING_TREE_AVG_TEXELS 6
#define HT_BINDING_TREE_MAX_TEXELS 7
#define HT_BINDING_HT_CENTERS_TEXELS 8
#define HT_BINDING_HT_CONES_TEXELS 9
#define HT_BINDING_FRONTIER_CHROMA_TEXELS 10    // ht-frontier: FrontierColours::chroma
#define HT_BINDING_FRONTIER_CENTROID_TEXELS 11  // ht-frontier: FrontierColours::centroid
#define HT_BINDING_FRONTIER_BINS_TEXELS 12      // ht-frontier: colour bins, four per uint (R32_UINT)
#define HT_BINDING_BVH_NODES 13  // GpuBvhNode[]: the spheres' BVH (host/bvh.h), depth first
#define HT_BINDING_BVH_ORDER 14  // uint[]: its sphere indices, leaf by leaf
#define HT_BINDING_CUT_TREE_TEXELS 15  // ht-cut: GpuScene::cutTree (R32G32B32A32_SFLOAT)
#define HT_BINDING_CUT_RECORD_TEXELS 16  // ht-cut: GpuScene::cutRecord (R32G32B32A32_SFLOAT)
#define HT_BINDING_CUT_LOOKUP_TEXELS 17  // ht-cut: EnvCut::lookup (R32_UINT)
// The spheres and their BVH again as texel views, for the same gathers:
#define HT_BINDING_SPHERE_TEXELS 18    // centre and radius per sphere (R32G32B32A32_SFLOAT)
#define HT_BINDING_BVH_NODE_TEXELS 19  // GpuBvhNode[] as two texels each (R32G32B32A32_UINT)
#define HT_BINDING_BVH_ORDER_TEXELS 20 // the BVH's sphere indices (R32_UINT)
#define HT_BVH_LEAF_SIZE 4       // spheres per leaf, at most (kBvhLeafSize)
#define HT_BINDING_COUNT 21

// Chunked arrays: element i lives in chunk i >> SHIFT at i & (2^SHIFT - 1).
#define HT_MAX_CHUNKS 128
#define HT_RADIANCE_CHUNK_SHIFT 23  // vec3: 96 MiB per chunk
#define HT_TREE_CHUNK_SHIFT 24      // float: 64 MiB per chunk
#define HT_HT_VEC3_CHUNK_SHIFT 23   // HT node centres (vec3): 96 MiB
#define HT_HT_VEC2_CHUNK_SHIFT 23   // HT node cos/sin radius (vec2): 64 MiB

// Method numbers: the values of ht::Method (below; host/methods/registry.cpp
// lists each method's spec in this order).
#define HT_METHOD_UNIFORM 0
#define HT_METHOD_COSINE 1
#define HT_METHOD_ENV 2
#define HT_METHOD_BRDF 3
#define HT_METHOD_MIS 4
#define HT_METHOD_HT 5
#define HT_METHOD_HT_VIS 6
#define HT_METHOD_HT_BIASED 7
#define HT_METHOD_HT_VIS_BIASED 8
#define HT_METHOD_ORACLE 9
#define HT_METHOD_WIS 10
#define HT_METHOD_WIS_BIASED 11
#define HT_METHOD_TSIS 12
#define HT_METHOD_RIS 13
#define HT_METHOD_HT_FRONTIER 14
#define HT_METHOD_MIS_COMPENSATED 15
#define HT_METHOD_RESTIR 16
#define HT_METHOD_RESTIR_BIASED 17
#define HT_METHOD_HT_CUT 18
#define HT_METHOD_ANY 0xFFFFFFFFu  // pixel.glsl's specialization constant: use GpuPush::method
#define HT_SPEC_METHOD 0           // its constant_id
#define HT_SPEC_TEXELS 1           // constant_id of bindings.glsl's kTexels
#define HT_SPEC_CAP_SLOTS 2        // constant_id of bindings.glsl's kCapSlots
#define HT_SPEC_BRDF_TABLE 3       // constant_id of bindings.glsl's kBrdfTable

// GpuPush::sampler: the values of ht::SamplerKind (host/sampler.h).
#define HT_SAMPLER_INDEPENDENT 0
#define HT_SAMPLER_STRATIFIED 1

// tsis: regions of the per-point partition (TsisPoint::kDefaultRegions) and
// the deepest level of its summed-area table (TsisTable::kMaxLevel).
#define HT_TSIS_REGIONS 32
#define HT_TSIS_MAX_LEVEL 9
// wis*: levels summed exactly (WisPoint::kExactLevels), their node count
// (levelOffset(kExactLevels + 1)) and the deepest order (WisPoint::kMaxOrder).
#define HT_WIS_EXACT_LEVELS 3
#define HT_WIS_TOP_NODES 1020
#define HT_WIS_MAX_ORDER 9

// ht*: GpuPush::htFlags bits. At most HT_MAX_CAPS occluders (caps) per
// shading point with visibility, HT_MAX_BUDGET_REFINEMENTS budget splits.
#define HT_FLAG_VISIBILITY 1u
#define HT_FLAG_BIASED 2u
#define HT_FLAG_BRDF_TABLE 4u
#define HT_FLAG_SPHERE_SEQUENCE 8u
#define HT_MAX_CAPS 16
// capSpheres' passes over the BVH: pass p visits the leaves that may hold a
// sphere whose sine reaches HT_CAP_FIRST_FLOOR / 4^p and that no earlier
// pass visited; the last visits the rest (kCapFloors).
#define HT_CAP_PASSES 4
#define HT_CAP_FIRST_FLOOR 0.25
#define HT_MAX_ORDER 13  // healpix::kMaxOrder
#define HT_MAX_BUDGET_REFINEMENTS 24
#define HT_MAX_WALK_LEVEL 24  // ht*: deepest (virtual) level of the walk, HtOptions::maxLevel
#define HT_SAMPLE_LOG_SLOTS 64
#define HT_PENDING_SLOTS 8  // ht*: accepted samples a pixel holds before shading them (GpuHtPending)
#define HT_LEAF_SLOTS 32  // ht*: leaves a pixel's walk records before accepting in them (GpuHtLeaf)
// ht* with table bounds: BrdfTable's sizes (host/brdf_table.h); per material
// HT_BRDF_TABLE_FLOATS floats: the averages, then the max pyramid's levels.
#define HT_BRDF_TABLE_THETA_O 16
#define HT_BRDF_TABLE_THETA 64
#define HT_BRDF_TABLE_PHI 128
#define HT_BRDF_TABLE_LEVELS 7
#define HT_BRDF_TABLE_MARGIN 1.25  // BrdfTable::kMargin: the maxima's safety factor
#define HT_BRDF_TABLE_CELLS (HT_BRDF_TABLE_THETA_O * HT_BRDF_TABLE_THETA * HT_BRDF_TABLE_PHI)
#define HT_BRDF_TABLE_FLOATS (2 * HT_BRDF_TABLE_CELLS + 16 * (2048 + 512 + 128 + 32 + 8 + 2))

// ht-frontier: the CDF's segments (kFrontierColourBins colour bins x 12
// faces), the shared Lambert tables a scene may have (both sides of each
// plane), GpuFrontierPoint::table of a point with a table of its own, and
// GpuFrontierScene::flags.
#define HT_FRONTIER_SEGMENTS 192
// ht-cut: its cut's nodes lie at this level or above, and there are at most
// this many.
#define HT_CUT_MAX_LEVEL 7
#define HT_CUT_MAX_NODES 512
#define HT_CUT_HORIZON_FLOOR 0.015625  // kCutHorizonFloor (exact in float)
#define HT_CUT_MIN_SHARE 0.125       // kCutMinShare (exact in float)
// ht-cut's caps per point at most: the first this many occluder slots (of
// HT_MAX_CAPS), the largest spheres in what the planes leave, then the planes.
#define HT_CUT_MAX_CAPS 8
#define HT_CUT_VISIBILITY 1u
#define HT_CUT_COLOUR_CONTROL 2u
#define HT_FRONTIER_LANES 8  // ht-frontier's scratch: blocks of 8 pixels of a tile row, element by element
#define HT_FRONTIER_MAX_SHARED 32
// ht-frontier: the level of the environment's average around the mirror
// direction that sets a flat surface's specular lobe count.
#define HT_FRONTIER_LOBE_LEVEL 3
// ht-frontier: one direction with the lobe apart samples the lobe with a
// probability kept within [this, 1 - this] (frontierLobeMixture); exact in
// float and double.
#define HT_FRONTIER_MIXTURE_MIN 0.125
// kFrontierLobeRadii: node radii per half-width of a lobe they resolve.
#define HT_FRONTIER_LOBE_RADII 2.0
// ht-frontier: partly covered nodes down to this level weigh their children's
// mean visible share (kFrontierShareLevel).
#define HT_FRONTIER_SHARE_LEVEL 3
#define HT_FRONTIER_OWN 0xFFFFFFFFu
#define HT_FRONTIER_VISIBILITY 1u
#define HT_FRONTIER_COLOUR_ORDER 2u
#define HT_FRONTIER_COLOUR_CONTROL 4u
// ht-frontier: chunks of the chroma and of the centroids of the average
// tree's nodes above the leaves (HT_HT_VEC3_CHUNK_SHIFT elements each): maps
// up to Nside 2048.
#define HT_FRONTIER_CHROMA_CHUNKS 4

#define HT_MATERIAL_LAMBERT 0
#define HT_MATERIAL_PHONG 1
#define HT_MATERIAL_GGX 2

#ifdef __cplusplus
#include <cstddef>
#include <cstdint>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace ht {
enum class Method : uint32_t {
  Uniform = HT_METHOD_UNIFORM,
  Cosine = HT_METHOD_COSINE,
  Env = HT_METHOD_ENV,
  Brdf = HT_METHOD_BRDF,
  Mis = HT_METHOD_MIS,
  Ht = HT_METHOD_HT,
  HtVis = HT_METHOD_HT_VIS,
  HtBiased = HT_METHOD_HT_BIASED,
  HtVisBiased = HT_METHOD_HT_VIS_BIASED,
  Oracle = HT_METHOD_ORACLE,
  Wis = HT_METHOD_WIS,
  WisBiased = HT_METHOD_WIS_BIASED,
  Tsis = HT_METHOD_TSIS,
  Ris = HT_METHOD_RIS,
  HtFrontier = HT_METHOD_HT_FRONTIER,
  MisCompensated = HT_METHOD_MIS_COMPENSATED,
  Restir = HT_METHOD_RESTIR,
  RestirBiased = HT_METHOD_RESTIR_BIASED,
  HtCut = HT_METHOD_HT_CUT,
};
}  // namespace ht

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
layout(buffer_reference, scalar, buffer_reference_align = 4) readonly buffer UintChunk { uint v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 4) readonly buffer Vec4Chunk { vec4 v[]; };
#if HT_FP64
layout(buffer_reference, scalar, buffer_reference_align = 8) readonly buffer DoubleChunk { double v[]; };
#else
layout(buffer_reference, scalar, buffer_reference_align = 8) readonly buffer DoubleChunk { uvec2 v[]; };
#endif
layout(buffer_reference) buffer TsisScratch;
layout(buffer_reference) buffer PixelStates;
layout(buffer_reference) buffer HtPendingList;
layout(buffer_reference) buffer FrontierSceneRef;
layout(buffer_reference) buffer RestirPoints;
layout(buffer_reference) buffer RestirReservoirs;
layout(buffer_reference, scalar, buffer_reference_align = 4) buffer FrontierUints { uint v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 4) buffer FrontierVec3s { vec3 v[]; };
#if HT_FP64
layout(buffer_reference, scalar, buffer_reference_align = 8) buffer FrontierReals { double v[]; };
#else
layout(buffer_reference, scalar, buffer_reference_align = 4) buffer FrontierReals { float v[]; };
#endif
layout(buffer_reference) buffer FrontierNodes;
layout(buffer_reference) buffer FrontierHeaders;
layout(buffer_reference) buffer FrontierColourNodes;
#if HT_FP64
layout(buffer_reference, scalar, buffer_reference_align = 8) buffer WisScratch { double v[]; };
#else
layout(buffer_reference, scalar, buffer_reference_align = 8) buffer WisScratch { uvec2 v[]; };
#endif
#define HT_CHUNK_REF(type) type
#endif

// Per scene, uploaded once.
struct GpuScene {
  // Device addresses first: 8-byte aligned.
  HT_CHUNK_REF(Vec3Chunk) radiance[HT_MAX_CHUNKS];   // Environment::radiance
  HT_CHUNK_REF(FloatChunk) treeAvg[HT_MAX_CHUNKS];   // MaxAvgTree::avgv (mis-compensated: its own tree's)
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
  uint bvhNodeCount;  // 0: the rays scan every sphere
  vec3 camU;
  uint envOrder;      // Nside = 2^envOrder
  vec3 camV;
  uint envHasLight;   // 0: treeAvg has no mass, nothing to sample (an all-black map)
  float envCosYaw;
  float envSinYaw;
  uvec2 envPixelSolidAngleBits;  // double: 4 pi / (12 4^order), as (low, high) words
  float envPixelSolidAngle;      // the same in single precision (shaders without fp64)
  uint sphereCount;
  uint planeCount;
  uint materialCount;
  // tsis (HT_FP64 shader only): per-face summed-area tables of the
  // luminance at level tsisLevel, TsisTable::sat's layout; one buffer
  // (at most 12 (2^HT_TSIS_MAX_LEVEL + 1)^2 doubles, 25 MiB); 0 if absent.
  HT_CHUNK_REF(DoubleChunk) tsisSat;
  uint tsisLevel;
  uint tsisReserved;
  // ht* with table bounds: HT_BRDF_TABLE_FLOATS per material, in material order; 0 if absent.
  HT_CHUNK_REF(FloatChunk) htBrdfTables;
  // ht-frontier: its tables (GpuFrontierScene); 0 if absent.
  HT_CHUNK_REF(FrontierSceneRef) frontier;
  // restir*: the image's shading points (GpuRestirPoint per pixel) and two
  // sets of reservoirs, each GpuRestirReservoir[restirChains][pixels]; 0 if absent.
  HT_CHUNK_REF(RestirPoints) restirPoints;
  HT_CHUNK_REF(RestirReservoirs) restirReservoirs[2];
  uint restirChains;      // reuse chains per group of dispatches, at most
  uint restirNeighbours;  // k: neighbours per round
  uint restirRadius;      // neighbours within this many pixels in x and y
  uint restirRounds;      // r: rounds of spatial reuse
  // ht-cut (host/ht_cut.h): cutTree: three vec4 per tree node down to the
  // descent's last level, min(cutProductLevel, cutMomentLevel), in the
  // tree's layout (centre, power; first moment, 0; chroma, 0); cutRecord: four vec4
  // per node a point weighs in its loop over the cut, the K nodes then each
  // one's four children (centre, sine of its disc's radius; moment, power;
  // chroma, cos of its bounding radius; its sine, the disc's chord radius,
  // level and index in the tree's layout as floats); the lookup
  // (EnvCut::lookup); 0 if absent.
  HT_CHUNK_REF(Vec4Chunk) cutTree;
  HT_CHUNK_REF(Vec4Chunk) cutRecord;
  HT_CHUNK_REF(UintChunk) cutLookup;
  uint cutCount;         // K
  uint cutLookupLevel;
  uint cutMomentLevel;
  uint cutProductLevel;  // CutOptions::productLevel, at most cutMomentLevel
  uint cutFlags;         // HT_CUT_VISIBILITY, HT_CUT_COLOUR_CONTROL
  float cutLobeSpan;     // cutLobeShare's rho
  float cutMinPartial;   // CutOptions::minPartialVisibility
  float cutCapCosMargin, cutCapSinMargin;  // cos and sin of kCapMargin
  uint cutReserved;
  float cutDiscSin[32];    // EnvCut::discSin
  float cutDiscChord[32];  // EnvCut::discChord
  float cutOmega[32];      // EnvCut::omega
  float cutLevelCos[32];   // HtGeometry::levelCosRadius
  float cutLevelSin[32];   // HtGeometry::levelSinRadius
};

// restir*: the shading point of a pixel that hit the scene (material
// HT_RESTIR_NO_HIT where its camera ray escaped).
#define HT_RESTIR_NO_HIT 0xFFFFFFFFu
#define HT_RESTIR_MAX_NEIGHBOURS 16  // k, at most
#define HT_RESTIR_MAX_CHAINS 16      // chains per group of dispatches, at most
struct GpuRestirPoint {
  vec3 position;
  uint material;
  vec3 normal;
  float depth;  // along the camera's axis
  vec3 wo;
  uint planar;  // 1: on a plane
};

// restir*: one reuse chain's reservoir: the sample kept with the radiance
// its candidate had (env samples: their HEALPix pixel's, which a lookup of
// the direction may miss by a rounding), its unbiased contribution weight W
// and its confidence M (candidates behind it).
struct GpuRestirReservoir {
  vec3 dir;
  float W;
  vec3 radiance;
  uint M;
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

// A node of the spheres' BVH in the order of host/bvh.h (a node's left child
// follows it), for a traversal without a stack: `skip` is the node after its
// subtree, where the walk goes when the ray misses the box or the leaf is done.
struct GpuBvhNode {
  vec3 lo;
  uint skip;
  vec3 hi;
  uint leaf;  // 0: inner; else first sphere entry << 3 | count (1 to HT_BVH_LEAF_SIZE)
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
  uint status;      // HT_PIXEL_DONE, HT_PIXEL_LOOPS_CUT
};
#define HT_PIXEL_DONE 1u       // the estimate is complete
#define HT_PIXEL_LOOPS_CUT 2u  // the driver ended a loop early in this batch or an earlier one of the pass: the results are wrong

// Test only: one accepted HT sample (GpuPush::htSampleLog).
struct GpuHtSample {
  vec3 dir;         // world space
  float h;          // acceptance value
  uvec2 candidate;  // accepted VDC index (low, high words)
  uint level;       // level of the cell it was jittered in
  float weight;     // 1 / (s h)
};

// ht*: an accepted sample waiting to be shaded. A loop of its own jitters,
// shades and sums the samples in the order accepted (ht.glsl).
struct GpuHtPending {
  uint64_t sx;  // hreal bits: the sample's sub-cell (sx, sy) of a cells x cells grid
  uint64_t sy;
  uint64_t candidate;
  uint cellOrder;  // the cell: pixel cellPix at cellOrder
  uint cellPix;
  uint sampleIndex;  // k for the k-th accepted sample: its sampler sample
  uint level;
  float cells;
  float h;
  uint averaged;  // biased: the BRDF at brdfDir
  vec3 brdfDir;   // HEALPix frame
};

// ht*: a node the walk reached and left to the loops after it: a leaf of
// the map whose lowest candidate passed its bounds, to be valued and
// accepted in, or a biased stop, one averaged sample. GpuPush::htPending
// holds HT_QUEUE_BYTES per tile pixel: every pixel's pending samples, then
// the leaves, the tile's pixels' k-th side by side (shaders/ht.glsl).
struct GpuHtLeaf {
  uint r;     // the node's lowest candidate (data levels: below 12 x 4^13 < 2^32)
  uint node;
  float h;    // a leaf: the path's smallest bound, then its value; a stop: its sample's h
  uint kind;  // the level, a leaf's visibility class << 8, HT_LEAF_STOP for a biased stop
};
#define HT_LEAF_STOP 0x10000u
#define HT_QUEUE_BYTES (HT_PENDING_SLOTS * 64 + HT_LEAF_SLOTS * 16)
#define HT_MAX_TILE_SIDE 256  // ht*: tiles of at most 256 x 256 pixels, for their queues

// Per tile pixel, kept from one dispatch of the tile to the next. A pixel's
// estimate runs in batches of GpuPush::batchLimit samples (HT: traversal
// steps), because Mesa's llvmpipe ends every loop of an invocation once its
// loops have run 65535 iterations in all, and so that no dispatch runs long.
// Reals are kept as their bits: doubles in the HT_FP64 shader, floats in the
// low word otherwise.
struct GpuPixelState {
  uint64_t sum[3];  // the estimate's running sum
  uint rng;         // the pixel's stream
  uint next;        // next sample index
  uint directions;
  uint shadowRays;
  uint htNodes;
  uint done;        // 1: the estimate is complete
  uint samplerSeed; // the pixel's sample points (PixelSampler's seed)
  uint loopsCut;    // 1: the driver ended a loop early in a batch of this pass
  // ht*: where the stackless traversal stands (ht.glsl).
  uint htSeed;
  uint htFace;
  uint htLevel;
  float htLeafH;
  uint64_t htNode;
  uint64_t htR;
  uint64_t htS;  // samples per unit of h
  uint64_t htU;  // the pixel's offset
  float htPathMin[HT_MAX_ORDER + 1];
  uint htResume;        // 1: the traversal stopped inside an acceptance (the pending list was full)
  uint pad2;
  uint64_t htResumeI;   // hreal bits: the next candidate of that acceptance
  // ht*: the recorded leaves (GpuHtLeaf), the next one to take, and the
  // walk inside the one taken (htCellActive 1), below the map's order.
  uint htLeafCount;
  uint htLeafNext;
  uint htCellActive;
  uint htCellLevel;
  uint64_t htCellNode;
  uint64_t htCellR;
};

// ht-frontier (host/ht_frontier.h). A table: its nodes along the nested
// index, their masses, the CDF's order of them (by segment) and the masses'
// prefix sums in that order. Reals are doubles in the HT_FP64 shader,
// floats otherwise.
struct GpuFrontierNode {
  uint level;
  uint node;
  float brdfBound;   // B
  float brdfCentre;  // BRDF x cos at the centre
  uint visibility;   // 1 free, 2 partly covered
  uint link;         // while refining: the candidate's parent
};
// A shared table's node's FrontierNode::chroma, descentChroma and kappa
// (grey on a shared table).
struct GpuFrontierColour {
  vec3 chroma;
  vec3 descent;
  float kappa;
};
struct GpuFrontierHeader {
  uint segStart[HT_FRONTIER_SEGMENTS + 1];  // first CDF position of each segment, and the end
  uint faceStart[13];                        // first node of each face, and the end
  uint count;      // nodes
  uint splits;
  uint brdfCount;  // n_b of this render's n directions
  uint nodeBase;   // shared tables: the first node and prefix sum in the shared arrays
  uint cumBase;
  uint pad;
};
// Per tile pixel, at the start of its scratch: what the batches after the
// first read.
struct GpuFrontierPoint {
  uint table;    // shared table, or HT_FRONTIER_OWN
  uint touched;  // faces where the point's caps change a shared table's masses
  uint nt;       // directions from the table
  uint nb;       // directions from the BRDF
  uint64_t total;  // real bits: the point's total mass
  uint64_t u;      // real bits: the systematic points' offset
};
// Per render. A pixel's scratch holds, at these byte offsets, its own table
// (header, nodes, order, masses, prefix sums; `capacity` nodes), the
// refinement's candidates and heap, and its masses, classes and prefix sums
// over a shared table (`sharedCapacity` nodes) under its caps.
struct GpuFrontierScene {
  HT_CHUNK_REF(FrontierUints) bins;  // colour bin per average-tree node, four per uint
  HT_CHUNK_REF(FrontierHeaders) sharedHeaders;
  HT_CHUNK_REF(FrontierNodes) sharedNodes;
  HT_CHUNK_REF(FrontierUints) sharedOrder;
  HT_CHUNK_REF(FrontierReals) sharedMass;
  HT_CHUNK_REF(FrontierReals) sharedCum;
  HT_CHUNK_REF(FrontierColourNodes) sharedColour;
  HT_CHUNK_REF(FrontierReals) sharedFaceColour;  // per table, FrontierTable::faceColour (12 x 4)
  HT_CHUNK_REF(Vec3Chunk) chroma[HT_FRONTIER_CHROMA_CHUNKS];    // FrontierColours::chroma
  HT_CHUNK_REF(Vec3Chunk) centroids[HT_FRONTIER_CHROMA_CHUNKS]; // FrontierColours::centroid
  vec3 sharedNormal[HT_FRONTIER_MAX_SHARED];  // HEALPix frame, as a point on the plane sees it
  float levelCosRadius[32];
  float levelSinRadius[32];
  uint sharedCount;
  uint refinements;  // splits of a point's own table
  uint capacity;
  uint sharedCapacity;
  float brdfFloor;
  float lobeFloor;
  float minPartialVisibility;
  float coarseRatio;
  float maxBrdfShare;
  uint productLevel;
  uint flags;  // HT_FRONTIER_*
  float capCosMargin;  // cos and sin of kCapMargin
  float capSinMargin;
  uint offHeader, offNodes, offOrder, offMass, offCum;
  uint offCandidates, offCandidateMass, offHeapKey, offHeapIndex;
  uint offCandidateKappa, offKappa;  // FrontierNode::kappa (vec3) of the candidates and of the table's nodes
  uint offPointMass, offPointClass, offPointCum, offSegCum;
  uint offColourAverage;  // Frontier::colourAverage: three reals
  uint pixelBytes;
};

// Per dispatch (at most 128 bytes on lavapipe).
// tsis: one region of a shading point's partition (TsisRegion); its doubles
// are uvec2 in the HT_FP64 = 0 shader, which has no tsis.
#if defined(__cplusplus) || HT_FP64
#define HT_DOUBLE double
#else
#define HT_DOUBLE uvec2
#endif
struct GpuTsisSlot {
  uint face, x0, y0, x1, y1;  // pixel rectangle [x0, x1) x [y0, y1) of a face at the table's level
  uint pad;
  HT_DOUBLE energy;    // the table's sum over it
  HT_DOUBLE brdf;      // BRDF weight
  HT_DOUBLE priority;  // while splitting; then the probability of the region
  HT_DOUBLE cdf;       // cumulative region weights
};
#undef HT_DOUBLE
#ifndef __cplusplus
layout(buffer_reference, scalar, buffer_reference_align = 8) buffer TsisScratch { GpuTsisSlot slots[]; };
layout(buffer_reference, scalar, buffer_reference_align = 8) buffer PixelStates { GpuPixelState s[]; };
layout(buffer_reference, scalar, buffer_reference_align = 8) buffer HtPendingList { GpuHtPending p[]; };
layout(buffer_reference, scalar, buffer_reference_align = 16) buffer HtLeafRef { GpuHtLeaf v; };
layout(buffer_reference, scalar, buffer_reference_align = 8) readonly buffer FrontierSceneRef { GpuFrontierScene f; };
layout(buffer_reference, scalar, buffer_reference_align = 4) buffer FrontierNodes { GpuFrontierNode v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 4) buffer FrontierHeaders { GpuFrontierHeader v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 4) buffer FrontierColourNodes { GpuFrontierColour v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 8) buffer FrontierPoints { GpuFrontierPoint v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 4) buffer RestirPoints { GpuRestirPoint v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 4) buffer RestirReservoirs { GpuRestirReservoir v[]; };
#endif

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
  // ht*: HtOptions (host/ht.h) of this render.
  uint htFlags;             // HT_FLAG_* | budgetRefinements << 8 | maxLevel << 16
  float htBrdfFloor;
  float htVisibilityFloor;
  float htBiasedSmoothness;
  uvec2 htSampleLog;        // test only: address of GpuHtSample[HT_SAMPLE_LOG_SLOTS per tile pixel], 0: off
  uint risCandidates;  // ris: candidates M per resampled sample
  // tsis: GpuTsisSlot[HT_TSIS_REGIONS per tile pixel], the partition of each
  // pixel's shading point (lavapipe turns private arrays indexed at run
  // time into long compare chains; memory it indexes directly).
  HT_CHUNK_REF(TsisScratch) tsisScratch;
  // wis*: HT_WIS_TOP_NODES doubles per tile pixel (WisPoint's exact levels).
  HT_CHUNK_REF(WisScratch) wisScratch;
  uint wisOrder;  // wis*: requested order of the sampled product
  uint samplerKind;  // HT_SAMPLER_*
  HT_CHUNK_REF(PixelStates) pixelState;  // GpuPixelState per tile pixel
  uint batch;       // 0: the tile's first dispatch, which starts every pixel
  uint batchLimit;  // samples (ht*: traversal steps) per pixel and dispatch
  uint canaryLoops; // iterations of the loop that tells whether loops were cut short
  uint canaryZero;  // always 0: keeps the compiler from folding that loop away
  HT_CHUNK_REF(HtPendingList) htPending;  // ht*: HT_QUEUE_BYTES per tile pixel
  uint64_t frontierScratch;  // ht-frontier: GpuFrontierScene::pixelBytes per tile pixel, rows in blocks of HT_FRONTIER_LANES
};

#ifdef __cplusplus
static_assert(sizeof(GpuScene) == 5 * 8 * HT_MAX_CHUNKS + 4 * 32 + 168 + 3 * 8 + 4 * 10 + 5 * 4 * 32);
static_assert(sizeof(GpuRestirPoint) == 48 && offsetof(GpuRestirPoint, depth) == 28 && sizeof(GpuRestirReservoir) == 32);
static_assert(sizeof(GpuFrontierNode) == 24 && sizeof(GpuFrontierHeader) == 4 * (HT_FRONTIER_SEGMENTS + 20) &&
              sizeof(GpuFrontierPoint) == 32 && offsetof(GpuFrontierPoint, total) == 16 &&
              sizeof(GpuFrontierColour) == 28);
static_assert(offsetof(GpuFrontierScene, sharedNormal) == 128 &&
              offsetof(GpuFrontierScene, levelCosRadius) == 128 + 12 * HT_FRONTIER_MAX_SHARED &&
              offsetof(GpuFrontierScene, sharedCount) == 128 + 12 * HT_FRONTIER_MAX_SHARED + 256 &&
              sizeof(GpuFrontierScene) == 128 + 12 * HT_FRONTIER_MAX_SHARED + 256 + 4 * 30);
static_assert(offsetof(GpuScene, htBrdfTables) - offsetof(GpuScene, camPosition) == 112 &&
              offsetof(GpuScene, frontier) - offsetof(GpuScene, camPosition) == 120);
static_assert(offsetof(GpuScene, tsisSat) - offsetof(GpuScene, camPosition) == 96 &&
              offsetof(GpuScene, tsisLevel) - offsetof(GpuScene, camPosition) == 104);
static_assert(offsetof(GpuScene, treeAvg) == 8 * HT_MAX_CHUNKS);
static_assert(offsetof(GpuScene, htLevelRadius) == 5 * 8 * HT_MAX_CHUNKS);
static_assert(offsetof(GpuScene, camPosition) == 5 * 8 * HT_MAX_CHUNKS + 4 * 32);
static_assert(offsetof(GpuScene, envPixelSolidAngleBits) - offsetof(GpuScene, camPosition) == 72);
static_assert(offsetof(GpuScene, materialCount) - offsetof(GpuScene, camPosition) == 92);
static_assert(sizeof(GpuMaterial) == 40 && offsetof(GpuMaterial, diffuse) == 4 &&
              offsetof(GpuMaterial, specular) == 16 && offsetof(GpuMaterial, specularProbability) == 36);
static_assert(sizeof(GpuSphere) == 20 && offsetof(GpuSphere, radius) == 12 && offsetof(GpuSphere, material) == 16);
static_assert(sizeof(GpuBvhNode) == 32 && offsetof(GpuBvhNode, hi) == 16 && offsetof(GpuBvhNode, leaf) == 28);
static_assert(sizeof(GpuPlane) == 28 && offsetof(GpuPlane, normal) == 12 && offsetof(GpuPlane, material) == 24);
static_assert(sizeof(GpuPixel) == 32 && offsetof(GpuPixel, shaded) == 12 && offsetof(GpuPixel, htNodes) == 24);
static_assert(sizeof(GpuPush) == 128 && offsetof(GpuPush, frontierScratch) == 120 && offsetof(GpuPush, htPending) == 112 && offsetof(GpuPush, seed) == 32 && offsetof(GpuPush, risCandidates) == 60 &&
              offsetof(GpuPush, tsisScratch) == 64 && offsetof(GpuPush, wisScratch) == 72 &&
              offsetof(GpuPush, wisOrder) == 80 && offsetof(GpuPush, pixelState) == 88 &&
              offsetof(GpuPush, batch) == 96 && offsetof(GpuPush, canaryLoops) == 104);
static_assert(sizeof(GpuPixelState) == 208 && offsetof(GpuPixelState, htCellNode) == 192 && offsetof(GpuPixelState, htResumeI) == 168 && offsetof(GpuPixelState, rng) == 24 &&
              offsetof(GpuPixelState, samplerSeed) == 48 && offsetof(GpuPixelState, htLeafH) == 68 &&
              offsetof(GpuPixelState, htNode) == 72 && offsetof(GpuPixelState, htPathMin) == 104);
static_assert(sizeof(GpuTsisSlot) == 56 && offsetof(GpuTsisSlot, energy) == 24 && offsetof(GpuTsisSlot, cdf) == 48);
static_assert(offsetof(GpuPush, htFlags) == 36 && offsetof(GpuPush, htSampleLog) == 52);
static_assert(sizeof(GpuHtLeaf) == 16 && offsetof(GpuHtLeaf, h) == 8);
static_assert(sizeof(GpuHtPending) == 64 && offsetof(GpuHtPending, cellOrder) == 24 &&
              offsetof(GpuHtPending, brdfDir) == 52);
static_assert(sizeof(GpuHtSample) == 32 && offsetof(GpuHtSample, candidate) == 16 && offsetof(GpuHtSample, level) == 24);
static_assert(sizeof(vec3) == 12 && alignof(vec3) == 4 && sizeof(vec2) == 8);

inline constexpr uint32_t kWorkgroupSize = HT_WORKGROUP_SIZE;
inline constexpr uint64_t kRadianceChunkElements = uint64_t(1) << HT_RADIANCE_CHUNK_SHIFT;
inline constexpr uint64_t kTreeChunkElements = uint64_t(1) << HT_TREE_CHUNK_SHIFT;
}  // namespace ht::gpu
#undef HT_CHUNK_REF
#endif

#endif  // HT_SHADERS_COMMON_H
