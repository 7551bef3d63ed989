// The GPU renderer's state (host/gpu_render.cpp: the device, pipelines,
// tiles, batches, timestamps, read-back; each method's uploads and scratch
// are its GpuMethodState, gpu_method.h). Private to the renderer.
#pragma once

#include <algorithm>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common.h"  // shaders/common.h
#include "gpu_method.h"
#include "gpu_render.h"
#include "vk/buffers.h"
#include "vk/device.h"
#include "vk/pipeline.h"

namespace ht {

// The shared header's structs (GpuPush, GpuScene, ...) by their names.
using namespace ht::gpu;

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
  vk::Buffer sceneBuffer, materials, spheres, planes, bvhNodes, bvhOrder;
  vk::Buffer sphereShapes;  // centre and radius per sphere, for HT_BINDING_SPHERE_TEXELS
  // Per texel binding, its format and the buffer (first chunk) it views,
  // null until that array is uploaded. bindScene gives a binding without a
  // buffer, and every binding when the arrays do not fit texel views
  // (kTexels off), a one-word placeholder of its format.
  std::map<uint32_t, TexelBinding> texelBuffers{
      {HT_BINDING_RADIANCE_TEXELS, {VK_FORMAT_R32_SFLOAT}},        {HT_BINDING_TREE_AVG_TEXELS, {VK_FORMAT_R32_SFLOAT}},
      {HT_BINDING_TREE_MAX_TEXELS, {VK_FORMAT_R32_SFLOAT}},        {HT_BINDING_HT_CENTERS_TEXELS, {VK_FORMAT_R32_SFLOAT}},
      {HT_BINDING_HT_CONES_TEXELS, {VK_FORMAT_R32_SFLOAT}},        {HT_BINDING_FRONTIER_CHROMA_TEXELS, {VK_FORMAT_R32_SFLOAT}},
      {HT_BINDING_FRONTIER_CENTROID_TEXELS, {VK_FORMAT_R32_SFLOAT}}, {HT_BINDING_FRONTIER_BINS_TEXELS, {VK_FORMAT_R32_UINT}},
      {HT_BINDING_CUT_TREE_TEXELS, {VK_FORMAT_R32G32B32A32_SFLOAT}},      {HT_BINDING_CUT_RECORD_TEXELS, {VK_FORMAT_R32G32B32A32_SFLOAT}},
      {HT_BINDING_CUT_LOOKUP_TEXELS, {VK_FORMAT_R32_UINT}},
      {HT_BINDING_SPHERE_TEXELS, {VK_FORMAT_R32G32B32A32_SFLOAT}},   {HT_BINDING_BVH_NODE_TEXELS, {VK_FORMAT_R32G32B32A32_UINT}},
      {HT_BINDING_BVH_ORDER_TEXELS, {VK_FORMAT_R32_UINT}}};
  // The scene's own (setScene's), which each render starts from before its
  // method fills its part.
  std::map<uint32_t, TexelBinding> sceneTexels;
  GpuScene sceneFields{};
  std::map<VkFormat, vk::Buffer> placeholders;
  // Per tile.
  // The shaders write each pixel's result on the device; one copy per
  // submission brings them to the host (a shader's scattered writes to
  // host memory cross the bus slowly on a discrete GPU).
  vk::Buffer pixels;
  vk::Buffer pixelsHost;
  vk::Buffer pixelState;   // GpuPixelState per tile pixel
  // What the scene's buffer holds (uploaded when it changes).
  GpuScene scene{};
  const Scene* hostScene = nullptr;
  int envOrder = 0;
  size_t materialCount = 0;
  size_t occluders = 0;
  size_t rayCost = 0;  // spheres and planes a ray tests, roughly
  // The methods' uploads and scratch for this scene, one per GpuSupport::makeState.
  std::map<std::unique_ptr<GpuMethodState> (*)(), std::unique_ptr<GpuMethodState>> states;
  bool recordHtSamples = false;

  // The shader variant the method runs in.
  bool usesFloat64(Method method) const {
    if (!ctx.float64) return false;
    return precision == GpuPrecision::Fp64 || (precision == GpuPrecision::Auto && methodSpec(method).gpu->float64);
  }
  void uploadTables(const RenderSettings& s, const MethodTables& tables);
  void checkMethod(const RenderSettings& s) const;
  // The method's state for this scene (null: it has none).
  GpuMethodState* methodState(Method method);
  std::pair<uint32_t, uint32_t> prepareTiles(const RenderSettings& s);
  // A tile's push constants, batch fields aside; with its scratch.
  GpuPush tilePush(const RenderSettings& s, uint32_t x, uint32_t y, uint32_t tileW, uint32_t tileH);
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
