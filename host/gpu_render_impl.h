// The GPU renderer's state, shared by its two halves: gpu_render.cpp (the
// device, pipelines, tiles, batches, timestamps, read-back) and
// gpu_methods.cpp (what each method family uploads, pushes and keeps as
// scratch). Private to them.
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common.h"  // shaders/common.h
#include "gpu_render.h"
#include "vk/buffers.h"
#include "vk/device.h"
#include "vk/pipeline.h"

namespace ht {

// The shared header's structs (GpuPush, GpuScene, ...) by their names, in
// both halves of the renderer.
using namespace ht::gpu;

class BrdfTable;
struct FrontierColours;
struct HtGeometry;
struct MaxAvgTree;
struct TsisTable;

namespace gpu_detail {

// Uploads `count` elements of `elementSize` bytes in chunks of
// `chunkElements`, each its own buffer; writes their addresses.
void uploadChunked(vk::Context& ctx, const void* data, uint64_t count, size_t elementSize, uint64_t chunkElements,
                   std::vector<vk::Buffer>& buffers, uint64_t* addresses, const char* what);

// A storage buffer holding `items` (at least one element, so that it exists).
template <typename T>
vk::Buffer uploadArray(vk::Context& ctx, const std::vector<T>& items) {
  vk::Buffer b(ctx, std::max<size_t>(items.size(), 1) * sizeof(T), vk::MemoryUse::DeviceLocal);
  b.upload(items.data(), items.size() * sizeof(T));
  return b;
}

// The compute shader of a method's family (shaders/<name>.comp.glsl), or null.
const char* familyShader(Family f);
// Samples (ht*: traversal steps) per pixel and dispatch, a first guess.
uint32_t firstBatchLimit(const RenderSettings& s, int envOrder, size_t shapes);
// Directions a pixel draws, roughly.
uint64_t directionsPerPixel(const RenderSettings& s);
// A tile's push constants, batch fields aside.
GpuPush tilePush(const RenderSettings& s, uint32_t x, uint32_t y, uint32_t tileW, uint32_t tileH);
// HT's BRDF bounds come from tables (HtOptions::brdfTable).
bool usesBrdfTable(const RenderSettings& s);

}  // namespace gpu_detail

struct GpuRenderer::Impl {
  vk::Context ctx;
  GpuDeviceInfo info;
  GpuPrecision precision;
  std::string shaderDir;
  std::string shaderName;  // the current pipeline's SPIR-V file
  std::optional<vk::ComputePipeline> pipeline;
  uint32_t pipelineMethod = HT_METHOD_ANY;  // what the pipeline is specialized for
  bool texelViews = true;       // GpuOptions::texelViews
  bool texels = false;          // the scene's arrays fit their texel views (HT_SPEC_TEXELS)
  bool pipelineTexels = false;  // the pipeline's HT_SPEC_TEXELS
  uint32_t pipelineCapSlots = 0;  // the pipeline's HT_SPEC_CAP_SLOTS
  bool pipelineBrdfTable = false;  // the pipeline's HT_SPEC_BRDF_TABLE
  bool pipelineRan = false;     // warmPipeline has dispatched it
  VkQueryPool queries = VK_NULL_HANDLE;
  uint64_t timestampMask = 0;
  uint32_t maxTileSide = 512;
  uint32_t batchLimit = 0;

  // Per scene.
  bool hasScene = false;
  std::vector<vk::Buffer> chunks;
  vk::Buffer sceneBuffer, materials, spheres, planes;
  // Per texel binding, its format and the buffer (first chunk) it views,
  // null until that array is uploaded. bindScene gives a binding without a
  // buffer, and every binding when the arrays do not fit texel views
  // (kTexels off), a one-word placeholder of its format.
  struct TexelBinding {
    VkFormat format;
    vk::Buffer* buffer = nullptr;
  };
  std::map<uint32_t, TexelBinding> texelBuffers{
      {HT_BINDING_RADIANCE_TEXELS, {VK_FORMAT_R32_SFLOAT}},        {HT_BINDING_TREE_AVG_TEXELS, {VK_FORMAT_R32_SFLOAT}},
      {HT_BINDING_TREE_MAX_TEXELS, {VK_FORMAT_R32_SFLOAT}},        {HT_BINDING_HT_CENTERS_TEXELS, {VK_FORMAT_R32_SFLOAT}},
      {HT_BINDING_HT_CONES_TEXELS, {VK_FORMAT_R32_SFLOAT}},        {HT_BINDING_FRONTIER_CHROMA_TEXELS, {VK_FORMAT_R32_SFLOAT}},
      {HT_BINDING_FRONTIER_CENTROID_TEXELS, {VK_FORMAT_R32_SFLOAT}}, {HT_BINDING_FRONTIER_BINS_TEXELS, {VK_FORMAT_R32_UINT}}};
  std::map<VkFormat, vk::Buffer> placeholders;
  // Per tile.
  // The shaders write each pixel's result on the device; one copy per
  // submission brings them to the host (a shader's scattered writes to
  // host memory cross the bus slowly on a discrete GPU).
  vk::Buffer pixels;
  vk::Buffer pixelsHost;
  vk::Buffer pixelState;   // GpuPixelState per tile pixel
  vk::Buffer tsisScratch;  // GpuTsisSlot per region and tile pixel
  vk::Buffer wisScratch;   // HT_WIS_TOP_NODES doubles per tile pixel
  vk::Buffer htPending;    // per tile pixel its pending samples and recorded leaves
  vk::Buffer frontierScratch;  // ht-frontier: GpuFrontierScene::pixelBytes per tile pixel, rows in blocks of HT_FRONTIER_LANES
  // The method's tables, uploaded at their first render (the scene struct
  // uploaded again), with what they were made from.
  GpuScene scene{};
  const Scene* hostScene = nullptr;
  int envOrder = 0;
  size_t materialCount = 0;
  size_t occluders = 0;
  std::shared_ptr<const HtGeometry> geometry;
  std::vector<vk::Buffer> geometryBuffers;
  std::vector<std::shared_ptr<const BrdfTable>> brdfTables;
  vk::Buffer brdfBuffer;
  std::shared_ptr<const TsisTable> tsis;
  vk::Buffer tsisBuffer;
  // ht-frontier: its colour bins and chroma (per map) and, per render, its shared
  // tables and settings (GpuFrontierScene).
  std::shared_ptr<const FrontierColours> frontierColours;
  vk::Buffer frontierBinsBuffer;
  std::vector<vk::Buffer> frontierChromaBuffers, frontierCentroidBuffers;
  uint64_t frontierChroma[HT_FRONTIER_CHROMA_CHUNKS] = {};
  uint64_t frontierCentroid[HT_FRONTIER_CHROMA_CHUNKS] = {};
  std::vector<vk::Buffer> frontierBuffers;
  GpuFrontierScene frontier{};
  // The map's average tree as setScene uploaded it, and mis-compensated's
  // own, which takes its place (GpuScene::treeAvg) while that method renders.
  uint64_t envTreeAvg[HT_MAX_CHUNKS] = {};
  vk::Buffer* envTreeAvgTexels = nullptr;
  uint32_t envHasLight = 0;
  std::shared_ptr<const MaxAvgTree> compensated;
  std::vector<vk::Buffer> compensatedBuffers;
  uint64_t compensatedTreeAvg[HT_MAX_CHUNKS] = {};
  bool samplingCompensated = false;
  bool recordHtSamples = false;
  vk::Buffer htSampleLog;

  // The shader variant the method runs in.
  bool usesFloat64(Method method) const {
    if (!ctx.float64) return false;
    return precision == GpuPrecision::Fp64 || (precision == GpuPrecision::Auto && methodInfo(method).gpuFloat64);
  }
  void uploadTables(const RenderSettings& s, const MethodTables& tables);
  void uploadFrontier(const RenderSettings& s, const MethodTables& tables);
  void checkMethod(const RenderSettings& s) const;
  std::pair<uint32_t, uint32_t> prepareTiles(const RenderSettings& s);
  // gpu_methods.cpp: what the method asks of a tile: its largest side, its
  // scratch bytes per pixel, its scratch buffers (made through
  // `deviceBuffer`, which fills a new one before the render) and their
  // addresses in the push constants.
  uint32_t methodTileSide(const RenderSettings& s) const;
  uint64_t scratchBytesPerPixel(const RenderSettings& s) const;
  void prepareScratch(const RenderSettings& s, uint32_t tileW, uint32_t tileH,
                      const std::function<bool(vk::Buffer&, VkDeviceSize)>& deviceBuffer);
  void bindScratch(const RenderSettings& s, GpuPush& push) const;
  std::pair<double, double> submitBatches(GpuPush& push, uint32_t first, uint32_t count, uint32_t limit);
  void warmPipeline(const RenderSettings& s);
  void renderTile(const RenderSettings& s, GpuPush& push, uint32_t& limit, GpuRenderResult& out);
  void readTile(const RenderSettings& s, const GpuPush& push, GpuRenderResult& out);
  explicit Impl(const GpuOptions& o);
  ~Impl();
  // The method's family shader specialized for it (HT_SPEC_METHOD) and for
  // whether HT's BRDF bounds are tabulated, with the buffers bound so far
  // bound again.
  void usePipeline(Method method, bool brdfTable);
  // The scene's buffers and texel views (placeholders without kTexels or
  // where an array is not uploaded).
  void bindScene();
};

}  // namespace ht
