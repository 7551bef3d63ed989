#include "gpu_method.h"

#include <algorithm>

#include <fmt/format.h>

#include "error.h"
#include "ht.h"
#include "tables.h"

namespace ht {

void uploadChunked(vk::Context& ctx, const void* data, uint64_t count, size_t elementSize, uint64_t chunkElements,
                   std::vector<vk::Buffer>& buffers, uint64_t* addresses, const char* what) {
  const uint64_t chunks = (count + chunkElements - 1) / chunkElements;
  if (chunks > HT_MAX_CHUNKS)
    throw Error(fmt::format("{}: {} elements exceed the GPU path's {} chunks of {}", what, count, HT_MAX_CHUNKS,
                            chunkElements));
  for (uint64_t c = 0; c < chunks; ++c) {
    const uint64_t first = c * chunkElements;
    const uint64_t n = std::min(chunkElements, count - first);
    vk::Buffer b(ctx, n * elementSize, vk::MemoryUse::DeviceLocal);
    b.upload(static_cast<const char*>(data) + first * elementSize, n * elementSize);
    addresses[c] = b.address();
    buffers.push_back(std::move(b));
  }
}

void GpuHtGeometry::upload(GpuUploadContext& c, const MethodTables& t) {
  const HtGeometry& g = t.geometry();
  if (uploaded != t.htGeometry) {
    if (g.order != c.envOrder) throw Error("internal: HT geometry of another order than the map's");
    buffers.clear();
    std::fill(std::begin(centers), std::end(centers), uint64_t(0));
    std::fill(std::begin(cosSinRadius), std::end(cosSinRadius), uint64_t(0));
    uploadChunked(c.ctx, g.centers.data(), g.centers.size(), sizeof(glm::vec3), uint64_t(1) << HT_HT_VEC3_CHUNK_SHIFT,
                  buffers, centers, "HT node centres");
    cones = buffers.size();
    uploadChunked(c.ctx, g.cosSinRadius.data(), g.cosSinRadius.size(), sizeof(glm::vec2),
                  uint64_t(1) << HT_HT_VEC2_CHUNK_SHIFT, buffers, cosSinRadius, "HT node radii");
    uploaded = t.htGeometry;
  }
  std::copy(std::begin(centers), std::end(centers), c.scene.htCenters);
  std::copy(std::begin(cosSinRadius), std::end(cosSinRadius), c.scene.htCosSinRadius);
  static_assert(sizeof(c.scene.htLevelRadius) == sizeof(g.levelRadius));
  std::copy(g.levelRadius.begin(), g.levelRadius.end(), c.scene.htLevelRadius);
  c.texels[HT_BINDING_HT_CENTERS_TEXELS].buffer = &buffers[0];
  c.texels[HT_BINDING_HT_CONES_TEXELS].buffer = &buffers[cones];
}

}  // namespace ht
