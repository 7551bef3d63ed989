// What each method family asks of the GPU renderer: its shader, the cost
// of its samples, its push constants, the tables it uploads and the
// scratch a tile keeps for it (the renderer proper: gpu_render.cpp).
#include <algorithm>
#include <cstring>

#include <fmt/format.h>
#include <glm/geometric.hpp>

#include "brdf_table.h"
#include "error.h"
#include "gpu_render_impl.h"
#include "healpix.h"
#include "ht.h"
#include "ht_frontier.h"
#include "sampling.h"
#include "tables.h"
#include "tree.h"
#include "tsis.h"
#include "wis.h"

namespace ht {

static_assert(BrdfTable::kMargin == float(HT_BRDF_TABLE_MARGIN));
static_assert(uint32_t(SamplerKind::Independent) == HT_SAMPLER_INDEPENDENT &&
              uint32_t(SamplerKind::Stratified) == HT_SAMPLER_STRATIFIED);
static_assert(FrontierTable::kSegments == HT_FRONTIER_SEGMENTS && kFrontierColourBins * 12 == HT_FRONTIER_SEGMENTS);
static_assert(int(Method::HtFrontier) == HT_METHOD_HT_FRONTIER);
static_assert(kFrontierLobeLevel == HT_FRONTIER_LOBE_LEVEL);
static_assert(kFrontierMixtureMin == HT_FRONTIER_MIXTURE_MIN);
static_assert(kFrontierLobeRadii == HT_FRONTIER_LOBE_RADII);
static_assert(kFrontierShareLevel == HT_FRONTIER_SHARE_LEVEL);
static_assert(TsisPoint::kDefaultRegions == HT_TSIS_REGIONS && TsisTable::kMaxLevel == HT_TSIS_MAX_LEVEL);
static_assert(WisPoint::kExactLevels == HT_WIS_EXACT_LEVELS && WisPoint::kMaxOrder == HT_WIS_MAX_ORDER &&
              MaxAvgTree::levelOffset(HT_WIS_EXACT_LEVELS + 1) == HT_WIS_TOP_NODES);
// The largest summed-area table fits one buffer (GpuScene::tsisSat).
static_assert(12ull * ((1ull << HT_TSIS_MAX_LEVEL) + 1) * ((1ull << HT_TSIS_MAX_LEVEL) + 1) * sizeof(double) <=
              (96ull << 20));
static_assert(int(MaterialType::Lambert) == HT_MATERIAL_LAMBERT && int(MaterialType::Phong) == HT_MATERIAL_PHONG &&
              int(MaterialType::Ggx) == HT_MATERIAL_GGX);

namespace gpu_detail {

// Loop iterations one pixel may spend in one dispatch, a quarter of what
// llvmpipe allows an invocation in all (GpuPixelState).
constexpr uint64_t kLoopIterationsPerBatch = 16384;

// Samples (ht*: traversal steps) per pixel and dispatch, from a rough count
// of the loop iterations each costs. Only the first guess: a dispatch whose
// loops were cut short makes the renderer halve it and start the tile again.
uint32_t firstBatchLimit(const RenderSettings& s, int envOrder, size_t shapes) {
  const uint64_t spp = uint64_t(std::max(s.spp, 1));
  const uint64_t descent = uint64_t(envOrder) + 4 + shapes;  // one environment sample and its shadow ray
  uint64_t cost = descent;
  switch (s.method) {
    case Method::Mis:
    case Method::MisCompensated: cost = 2 * descent; break;
    case Method::Ris: cost = uint64_t(std::max(s.options.risCandidates, 1)) * descent + shapes; break;
    case Method::Tsis: cost = 2 * HT_TSIS_REGIONS + 4 * descent; break;
    case Method::Wis:
    case Method::WisBiased: {
      const int order = std::clamp(s.options.wisOrder, 0, std::min(envOrder, HT_WIS_MAX_ORDER));
      cost = 12 + 4 * uint64_t(order) + descent;
      if (s.method == Method::WisBiased) cost += uint64_t(1) << (2 * (envOrder - order));
      break;
    }
    case Method::Ht:
    case Method::HtVis:
    case Method::HtBiased:
    // A step of the walk is one node: its loop, and the caps' (ht-vis);
    // its share of the leaves' visible fractions and of the samples' shading
    // grows with the samples per pixel (measured, ht-vis on spheres.json at
    // 96x48: the longest batch within llvmpipe's loop limit was 4096 steps at
    // 64 spp, 1024 at 256, 512 at 1024).
    case Method::HtVisBiased: cost = (4 + 2 * shapes) * std::max<uint64_t>(1, spp / 64); break;
    // Per direction a descent of four children a level, each under the
    // caps, and a few binary searches.
    case Method::HtFrontier: cost = uint64_t(envOrder) * (4 + 4 * shapes) + 40 + descent; break;
    default: break;
  }
  return uint32_t(std::clamp<uint64_t>(kLoopIterationsPerBatch / cost, 1, 1u << 20));
}

// The compute shader of a method's family (shaders/<name>.comp.glsl).
const char* familyShader(Family f) {
  switch (f) {
    case Family::Baseline: return "baselines";
    case Family::Ht: return "ht";
    case Family::Competitor: return "competitors";
    case Family::Product: return "frontier";
    default: return nullptr;
  }
}

// A tile's push constants, batch fields aside.
GpuPush tilePush(const RenderSettings& s, uint32_t x, uint32_t y, uint32_t tileW, uint32_t tileH) {
  GpuPush push{};
  push.width = uint32_t(s.width);
  push.height = uint32_t(s.height);
  push.tileX = x;
  push.tileY = y;
  push.tileWidth = std::min(tileW, uint32_t(s.width) - x);
  push.tileHeight = std::min(tileH, uint32_t(s.height) - y);
  push.method = uint32_t(s.method);
  push.spp = uint32_t(std::max(s.spp, 1));
  push.seed = s.seed;
  if (methodInfo(s.method).family == Family::Ht) {
    // HtOptions as estimateDirect (host/integrator.cpp) sets them.
    const HtOptions ho = htOptionsFor(s.method, s.options);
    if (ho.budgetRefinements > HT_MAX_BUDGET_REFINEMENTS || ho.maxLevel > HT_MAX_WALK_LEVEL)
      throw Error("internal: HtOptions beyond the shaders' limits");
    push.htFlags = (ho.visibility ? HT_FLAG_VISIBILITY : 0u) | (ho.biased ? HT_FLAG_BIASED : 0u) |
                   (ho.brdfTable ? HT_FLAG_BRDF_TABLE : 0u) | (ho.sphereSequence ? HT_FLAG_SPHERE_SEQUENCE : 0u) |
                   uint32_t(ho.budgetRefinements) << 8 | uint32_t(ho.maxLevel) << 16;
    push.htBrdfFloor = ho.brdfFloor;
    push.htVisibilityFloor = ho.visibilityFloor;
    push.htBiasedSmoothness = ho.biasedSmoothness;
  }
  push.risCandidates = uint32_t(std::max(s.options.risCandidates, 1));
  push.wisOrder = uint32_t(std::max(s.options.wisOrder, 0));
  push.samplerKind = uint32_t(s.options.sampler);
  push.canaryLoops = 2;
  push.canaryZero = 0;
  return push;
}

// HT's BRDF bounds come from tables (HtOptions::brdfTable).
bool usesBrdfTable(const RenderSettings& s) {
  return methodInfo(s.method).family == Family::Ht && htOptionsFor(s.method, s.options).brdfTable;
}

// Directions a pixel draws, roughly: ris draws M candidates per sample;
// tsis first partitions the sphere (about five BRDF evaluations per region);
// wis evaluates the BRDF at every node of its exact levels, then four times
// per level below them.
uint64_t directionsPerPixel(const RenderSettings& s) {
  const uint64_t spp = uint64_t(std::max(s.spp, 1));
  switch (s.method) {
    case Method::Mis:
    case Method::MisCompensated: return 2 * spp;
    case Method::Ris: return spp * uint64_t(std::max(s.options.risCandidates, 1));
    case Method::Tsis: return spp + 5 * HT_TSIS_REGIONS;
    case Method::Wis:
    case Method::WisBiased: return 4 * spp * (HT_WIS_MAX_ORDER - HT_WIS_EXACT_LEVELS) + HT_WIS_TOP_NODES;
    default: return spp;
  }
}

}  // namespace gpu_detail

using namespace gpu_detail;

bool gpuSupportsMethod(Method m) { return methodInfo(m).gpu && familyShader(methodInfo(m).family); }

std::string gpuSceneLimit(Method method, size_t occluders) {
  const MethodInfo& info = methodInfo(method);
  if ((info.family == Family::Ht || method == Method::HtFrontier) && info.visibility && occluders > HT_MAX_CAPS)
    return fmt::format("method {} on the GPU handles at most {} spheres and planes (the scene has {}); "
                       "use --device cpu", methodName(method), HT_MAX_CAPS, occluders);
  return {};
}

// The tables the method reads, uploaded at its first render (and again when
// they are other tables), so that the other methods never build them.
void GpuRenderer::Impl::uploadTables(const RenderSettings& s, const MethodTables& t) {
  const MethodInfo& info = methodInfo(s.method);
  bool changed = false;
  // mis-compensated's environment technique descends its own tree, in the
  // map's tree's place while it renders (the map's is back for any other).
  const bool compensatedNow = s.method == Method::MisCompensated;
  if (compensatedNow && compensated != t.compensated) {
    const MaxAvgTree& tree = t.compensatedTree();
    compensatedBuffers.clear();
    uploadChunked(ctx, tree.avgv.data(), tree.avgv.size(), sizeof(float), kTreeChunkElements, compensatedBuffers,
                  compensatedTreeAvg, "mis-compensated tree");
    compensated = t.compensated;
    samplingCompensated = false;
  }
  if (compensatedNow != samplingCompensated) {
    std::copy(std::begin(compensatedNow ? compensatedTreeAvg : envTreeAvg),
              std::end(compensatedNow ? compensatedTreeAvg : envTreeAvg), scene.treeAvg);
    scene.envHasLight = compensatedNow ? (compensated->total() > 0.0 ? 1u : 0u) : envHasLight;
    texelBuffers[HT_BINDING_TREE_AVG_TEXELS].buffer = compensatedNow ? &compensatedBuffers[0] : envTreeAvgTexels;
    samplingCompensated = compensatedNow;
    changed = true;
  }
  if (info.family == Family::Ht || s.method == Method::HtFrontier) {
    if (const std::string limit = gpuSceneLimit(s.method, occluders); !limit.empty()) throw Error(limit);
    if (geometry != t.htGeometry) {
      const HtGeometry& g = t.geometry();
      if (g.order != envOrder) throw Error("internal: HT geometry of another order than the map's");
      geometryBuffers.clear();
      uploadChunked(ctx, g.centers.data(), g.centers.size(), sizeof(glm::vec3),
                    uint64_t(1) << HT_HT_VEC3_CHUNK_SHIFT, geometryBuffers, scene.htCenters, "HT node centres");
      const size_t cones = geometryBuffers.size();
      uploadChunked(ctx, g.cosSinRadius.data(), g.cosSinRadius.size(), sizeof(glm::vec2),
                    uint64_t(1) << HT_HT_VEC2_CHUNK_SHIFT, geometryBuffers, scene.htCosSinRadius, "HT node radii");
      texelBuffers[HT_BINDING_HT_CENTERS_TEXELS].buffer = &geometryBuffers[0];
      texelBuffers[HT_BINDING_HT_CONES_TEXELS].buffer = &geometryBuffers[cones];
      static_assert(sizeof(scene.htLevelRadius) == sizeof(g.levelRadius));
      std::copy(g.levelRadius.begin(), g.levelRadius.end(), scene.htLevelRadius);
      geometry = t.htGeometry;
      changed = true;
    }
    if (info.family == Family::Ht && s.options.brdfBounds == MethodOptions::BrdfBounds::Table &&
        brdfTables != t.brdfTables) {
      if (t.brdfTables.size() != materialCount) throw Error("internal: BRDF tables not prepared for every material");
      std::vector<float> all;
      for (const auto& table : t.brdfTables) {
        std::vector<float> f = table->flattened();
        if (f.size() != size_t(HT_BRDF_TABLE_FLOATS)) throw Error("internal: BRDF table size differs from the shaders'");
        all.insert(all.end(), f.begin(), f.end());
      }
      brdfBuffer = uploadArray(ctx, all);
      scene.htBrdfTables = brdfBuffer.address();
      brdfTables = t.brdfTables;
      changed = true;
    }
  }
  // tsis: its summed-area table, in doubles.
  if (s.method == Method::Tsis && scene.envHasLight != 0 && tsis != t.tsisTable()) {
    const TsisTable& sat = *t.tsisTable();
    tsisBuffer = vk::Buffer(ctx, sat.sat.size() * sizeof(double), vk::MemoryUse::DeviceLocal);
    tsisBuffer.upload(sat.sat.data(), sat.sat.size() * sizeof(double));
    scene.tsisSat = tsisBuffer.address();
    scene.tsisLevel = uint32_t(sat.level);
    tsis = t.tsis;
    changed = true;
  }
  if (s.method == Method::HtFrontier) {
    uploadFrontier(s, t);
    changed = true;
  }
  if (changed) {
    sceneBuffer.upload(&scene, sizeof(scene));
    bindScene();
  }
}

namespace {

// The normals (as a point on the plane sees them) of both sides of every
// plane: the shared tables ht-frontier uses.
std::vector<glm::vec3> sharedFrontierNormals(const Scene& scene) {
  std::vector<glm::vec3> normals;
  for (const Plane& p : scene.planes) {
    for (const glm::vec3& side : {p.normal, -p.normal}) {
      const glm::vec3 n = frontierSurfaceNormal(scene.environment, side);
      if (std::find(normals.begin(), normals.end(), n) == normals.end()) normals.push_back(n);
    }
  }
  return normals;
}

// A pixel's ht-frontier scratch, in bytes per pixel: GpuFrontierPoint, then
// each array 8-byte aligned (the shader multiplies by HT_FRONTIER_LANES,
// the pixels of a block, which it lays side by side), for f's capacities
// and `real`-byte reals.
void layOutFrontierScratch(uint32_t real, GpuFrontierScene& f) {
  const uint32_t candidates = 12 + 4 * f.refinements;
  uint32_t at = uint32_t(sizeof(GpuFrontierPoint));
  auto place = [&](uint32_t bytes) {
    const uint32_t o = at;
    at = (at + bytes + 7) / 8 * 8;
    return o;
  };
  f.offHeader = place(sizeof(GpuFrontierHeader));
  f.offNodes = place(f.capacity * sizeof(GpuFrontierNode));
  f.offOrder = place(f.capacity * 4);
  f.offMass = place(f.capacity * real);
  f.offCum = place((f.capacity + 1) * real);
  f.offCandidates = place(candidates * sizeof(GpuFrontierNode));
  f.offCandidateMass = place(candidates * real);
  f.offHeapKey = place(candidates * real);
  f.offHeapIndex = place(std::max<uint32_t>(candidates, HT_FRONTIER_SEGMENTS) * 4);  // also the counting sort's
  f.offCandidateKappa = place(candidates * 12);
  f.offKappa = place(f.capacity * 12);
  f.offPointMass = place(f.sharedCapacity * real);
  f.offPointClass = place(f.sharedCapacity * 4);
  f.offPointCum = place(f.sharedCapacity * real);
  f.offSegCum = place((HT_FRONTIER_SEGMENTS + 1) * real);
  f.offColourAverage = place(3 * real);
  f.pixelBytes = at;
}

}  // namespace

// ht-frontier's GpuFrontierScene for this render: frontierOptionsFor's
// options, the shared Lambert table of each side of each
// plane, and the layout of a pixel's scratch.
void GpuRenderer::Impl::uploadFrontier(const RenderSettings& s, const MethodTables& t) {
  const Scene& hs = *hostScene;
  const Environment& env = hs.environment;
  const HtGeometry& g = t.geometry();
  const FrontierColours& colours = t.colours();
  const std::vector<uint8_t>& bins = colours.bins;
  const FrontierOptions options = frontierOptionsFor(s.options);
  const int n = std::max(s.spp, 1);
  const bool fp64 = usesFloat64(s.method);
  if (frontierColours != t.frontierColours) {
    std::vector<uint32_t> packed((bins.size() + 3) / 4, 0u);
    for (size_t i = 0; i < bins.size(); ++i) packed[i / 4] |= uint32_t(bins[i]) << (8 * (i % 4));
    frontierBinsBuffer = uploadArray(ctx, packed);
    constexpr uint64_t chunk = uint64_t(1) << HT_HT_VEC3_CHUNK_SHIFT;
    if (colours.chroma.size() > HT_FRONTIER_CHROMA_CHUNKS * chunk)
      throw Error(fmt::format("method ht-frontier on the GPU handles maps up to Nside 2048 (this one has {} nodes "
                              "above its pixels, at most {}); use --device cpu",
                              colours.chroma.size(), HT_FRONTIER_CHROMA_CHUNKS * chunk));
    // A map of one level has no nodes above its pixels: one element, unread, so that the buffer exists.
    const std::vector<glm::vec3> none(1, glm::vec3(0.0f));
    auto upload = [&](const std::vector<glm::vec3>& v, std::vector<vk::Buffer>& buffers, uint64_t* addresses,
                      const char* what) {
      buffers.clear();
      std::fill(addresses, addresses + HT_FRONTIER_CHROMA_CHUNKS, uint64_t(0));
      const std::vector<glm::vec3>& data = v.empty() ? none : v;
      uploadChunked(ctx, data.data(), data.size(), sizeof(glm::vec3), chunk, buffers, addresses, what);
    };
    upload(colours.chroma, frontierChromaBuffers, frontierChroma, "ht-frontier chroma");
    upload(colours.centroid, frontierCentroidBuffers, frontierCentroid, "ht-frontier centroids");
    frontierColours = t.frontierColours;
    texelBuffers[HT_BINDING_FRONTIER_CHROMA_TEXELS].buffer = &frontierChromaBuffers[0];
    texelBuffers[HT_BINDING_FRONTIER_CENTROID_TEXELS].buffer = &frontierCentroidBuffers[0];
    texelBuffers[HT_BINDING_FRONTIER_BINS_TEXELS].buffer = &frontierBinsBuffer;
  }
  GpuFrontierScene& f = frontier;
  f = GpuFrontierScene{};
  f.bins = frontierBinsBuffer.address();
  std::copy(std::begin(frontierChroma), std::end(frontierChroma), f.chroma);
  std::copy(std::begin(frontierCentroid), std::end(frontierCentroid), f.centroids);

  const std::vector<glm::vec3> normals =
      options.sharedRefinements >= 0 ? sharedFrontierNormals(hs) : std::vector<glm::vec3>{};
  if (normals.size() > size_t(HT_FRONTIER_MAX_SHARED))
    throw Error(fmt::format("method ht-frontier on the GPU handles at most {} planes; use --device cpu",
                            HT_FRONTIER_MAX_SHARED / 2));
  std::vector<GpuFrontierHeader> headers;
  std::vector<GpuFrontierNode> nodes;
  std::vector<uint32_t> order;
  std::vector<double> mass, cum, faceColour;
  std::vector<GpuFrontierColour> colour;
  uint32_t sharedCapacity = 0;
  for (size_t k = 0; k < normals.size(); ++k) {
    FrontierTable table;
    buildSharedFrontierTable(env, g, normals[k], options, colours, table);
    GpuFrontierHeader h{};
    std::copy(table.segStart.begin(), table.segStart.end(), h.segStart);
    std::copy(table.faceStart.begin(), table.faceStart.end(), h.faceStart);
    h.count = uint32_t(table.nodes.size());
    h.splits = uint32_t(table.splits);
    h.brdfCount = uint32_t(frontierBrdfCount(table.coarseShare, options, n));
    h.nodeBase = uint32_t(nodes.size());
    h.cumBase = uint32_t(cum.size());
    headers.push_back(h);
    for (const FrontierNode& nd : table.nodes) {
      nodes.push_back({uint32_t(nd.level), uint32_t(nd.node), nd.brdfBound, nd.brdfCentre, uint32_t(nd.visibility), 0u});
      mass.push_back(nd.mass);
      colour.push_back({nd.chroma, nd.descentChroma, nd.kappa.x});
    }
    for (const glm::dvec4& c : table.faceColour) faceColour.insert(faceColour.end(), {c.x, c.y, c.z, c.w});
    order.insert(order.end(), table.cdfOrder.begin(), table.cdfOrder.end());
    cum.insert(cum.end(), table.cum.begin(), table.cum.end());
    sharedCapacity = std::max(sharedCapacity, h.count);
    f.sharedNormal[k] = normals[k];
  }
  // Reals in the shader variant's precision.
  auto reals = [&](const std::vector<double>& v) {
    if (fp64) return uploadArray(ctx, v);
    return uploadArray(ctx, std::vector<float>(v.begin(), v.end()));
  };
  frontierBuffers.clear();
  frontierBuffers.push_back(uploadArray(ctx, headers));
  frontierBuffers.push_back(uploadArray(ctx, nodes));
  frontierBuffers.push_back(uploadArray(ctx, order));
  frontierBuffers.push_back(reals(mass));
  frontierBuffers.push_back(reals(cum));
  frontierBuffers.push_back(uploadArray(ctx, colour));
  frontierBuffers.push_back(reals(faceColour));
  f.sharedHeaders = frontierBuffers[0].address();
  f.sharedNodes = frontierBuffers[1].address();
  f.sharedOrder = frontierBuffers[2].address();
  f.sharedMass = frontierBuffers[3].address();
  f.sharedCum = frontierBuffers[4].address();
  f.sharedColour = frontierBuffers[5].address();
  f.sharedFaceColour = frontierBuffers[6].address();
  f.sharedCount = uint32_t(normals.size());
  std::copy(g.levelCosRadius.begin(), g.levelCosRadius.end(), f.levelCosRadius);
  std::copy(g.levelSinRadius.begin(), g.levelSinRadius.end(), f.levelSinRadius);
  const uint32_t refinements = uint32_t(frontierRefinements(options, n));
  f.refinements = refinements;
  f.capacity = 12 + 3 * refinements;
  f.sharedCapacity = sharedCapacity;
  f.brdfFloor = options.brdfFloor;
  f.lobeFloor = options.lobeFloor;
  f.minPartialVisibility = options.minPartialVisibility;
  f.coarseRatio = options.coarseRatio;
  f.maxBrdfShare = options.maxBrdfShare;
  f.productLevel = uint32_t(std::max(options.productLevel, 0));
  f.flags = (options.visibility ? HT_FRONTIER_VISIBILITY : 0u) | (options.colourOrder ? HT_FRONTIER_COLOUR_ORDER : 0u) |
            (options.colourControl ? HT_FRONTIER_COLOUR_CONTROL : 0u);
  f.capCosMargin = std::cos(kCapMargin);
  f.capSinMargin = std::sin(kCapMargin);
  layOutFrontierScratch(fp64 ? 8 : 4, f);
  frontierBuffers.push_back(vk::Buffer(ctx, sizeof(GpuFrontierScene), vk::MemoryUse::DeviceLocal));
  frontierBuffers.back().upload(&f, sizeof(f));
  scene.frontier = frontierBuffers.back().address();
}

uint32_t GpuRenderer::Impl::methodTileSide(const RenderSettings& s) const {
  return methodInfo(s.method).family == Family::Ht ? uint32_t(HT_MAX_TILE_SIDE) : UINT32_MAX;
}

uint64_t GpuRenderer::Impl::scratchBytesPerPixel(const RenderSettings& s) const {
  return s.method == Method::HtFrontier ? frontier.pixelBytes : 0;
}

void GpuRenderer::Impl::prepareScratch(const RenderSettings& s, uint32_t tileW, uint32_t tileH,
                                       const std::function<bool(vk::Buffer&, VkDeviceSize)>& deviceBuffer) {
  const bool htMethod = methodInfo(s.method).family == Family::Ht;
  const VkDeviceSize tilePixels = VkDeviceSize(tileW) * tileH;
  if (s.method == Method::Tsis) deviceBuffer(tsisScratch, tilePixels * HT_TSIS_REGIONS * sizeof(GpuTsisSlot));
  if (s.method == Method::Wis || s.method == Method::WisBiased)
    deviceBuffer(wisScratch, tilePixels * HT_WIS_TOP_NODES * sizeof(double));
  // ht-frontier's scratch: blocks of HT_FRONTIER_LANES pixels of a tile row.
  const VkDeviceSize rowBlocks = (tileW + HT_FRONTIER_LANES - 1) / HT_FRONTIER_LANES;
  if (s.method == Method::HtFrontier)
    deviceBuffer(frontierScratch, rowBlocks * HT_FRONTIER_LANES * tileH * frontier.pixelBytes);
  static_assert(HT_QUEUE_BYTES == HT_PENDING_SLOTS * sizeof(GpuHtPending) + HT_LEAF_SLOTS * sizeof(GpuHtLeaf));
  if (htMethod) deviceBuffer(htPending, tilePixels * HT_QUEUE_BYTES);
  // The sample log is read on the host, not filled.
  const VkDeviceSize logBytes = tilePixels * HT_SAMPLE_LOG_SLOTS * sizeof(GpuHtSample);
  if (htMethod && recordHtSamples && htSampleLog.size() < logBytes)
    htSampleLog = vk::Buffer(ctx, logBytes, vk::MemoryUse::Readback);
}

// The tile's scratch buffers in its push constants.
void GpuRenderer::Impl::bindScratch(const RenderSettings& s, GpuPush& push) const {
  push.tsisScratch = s.method == Method::Tsis ? tsisScratch.address() : 0;
  push.wisScratch = s.method == Method::Wis || s.method == Method::WisBiased ? wisScratch.address() : 0;
  push.pixelState = pixelState.address();
  if (methodInfo(s.method).family == Family::Ht) push.htPending = htPending.address();
  if (s.method == Method::HtFrontier) push.frontierScratch = frontierScratch.address();
  if (methodInfo(s.method).family == Family::Ht && recordHtSamples) {
    const VkDeviceAddress a = htSampleLog.address();
    push.htSampleLog = glm::uvec2(uint32_t(a), uint32_t(a >> 32));
  }
}

}  // namespace ht
