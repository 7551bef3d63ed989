// A method's part of the Vulkan path: the tables it uploads, the fields of
// GpuScene and the texel views it fills, the scratch a tile keeps for it.
// Made through GpuSupport::makeState (method.h) and kept by the renderer
// for the scene (host/gpu_render.cpp); each family's is in host/methods/.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <vector>

#include "common.h"  // shaders/common.h
#include "vk/buffers.h"
#include "vk/device.h"

namespace ht {

struct GpuRenderResult;
struct HtGeometry;
struct MethodTables;
struct RenderSettings;
struct Scene;

// A texel binding's format and the buffer (first chunk) it views; without
// one, the renderer binds a one-word buffer of that format.
struct TexelBinding {
  VkFormat format;
  vk::Buffer* buffer = nullptr;
};

// What a method's upload reaches. Before each render the renderer resets
// `scene` and `texels` to the scene's own (setScene), so a method fills
// its fields at every upload, and uploads its buffers again only when its
// tables changed.
struct GpuUploadContext {
  vk::Context& ctx;
  const Scene& hostScene;
  gpu::GpuScene& scene;
  std::map<uint32_t, TexelBinding>& texels;
  bool fp64;  // the shader variant's reals are doubles
  int envOrder;
  size_t materialCount;
};

// What a tile's scratch reaches: `deviceBuffer` makes a buffer of at least
// the given size, filled before the render, and says whether it is new.
struct GpuTileContext {
  vk::Context& ctx;
  uint32_t tileW, tileH;
  const std::function<bool(vk::Buffer&, VkDeviceSize)>& deviceBuffer;
  bool recordHtSamples;  // GpuOptions::recordHtSamples
};

class GpuMethodState {
 public:
  virtual ~GpuMethodState() = default;
  virtual void upload(GpuUploadContext& c, const RenderSettings& s, const MethodTables& tables) = 0;
  virtual uint64_t scratchBytesPerPixel(const RenderSettings&) const { return 0; }
  virtual void prepareScratch(GpuTileContext&, const RenderSettings&) {}
  // The tile's scratch in its push constants.
  virtual void bindScratch(const RenderSettings&, gpu::GpuPush&) const {}
  // After a tile: what the method read back beyond the pixels.
  virtual void readTile(const RenderSettings&, const gpu::GpuPush&, const gpu::GpuPixel*, GpuRenderResult&) {}
};

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

// HT's node geometry (centres, cone radii) as ht* and ht-frontier read it:
// uploaded when the tables hold another, its addresses and views filled at
// every upload.
struct GpuHtGeometry {
  std::shared_ptr<const HtGeometry> uploaded;
  std::vector<vk::Buffer> buffers;
  size_t cones = 0;  // the first buffer of the radii
  uint64_t centers[HT_MAX_CHUNKS] = {}, cosSinRadius[HT_MAX_CHUNKS] = {};
  void upload(GpuUploadContext& c, const MethodTables& tables);
};

}  // namespace ht
