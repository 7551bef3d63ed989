// ht* on the Vulkan path: HT's node geometry, the BRDF tables with
// tabulated bounds, and per tile pixel its pending samples and recorded
// leaves (and, for tests, its first accepted samples).
#include <algorithm>

#include "brdf_table.h"
#include "error.h"
#include "gpu_method.h"
#include "gpu_render.h"
#include "ht.h"
#include "render.h"
#include "shared.h"
#include "tables.h"

namespace ht {
namespace {

static_assert(BrdfTable::kMargin == float(HT_BRDF_TABLE_MARGIN));

class HtGpuState : public GpuMethodState {
 public:
  void upload(GpuUploadContext& c, const RenderSettings& s, const MethodTables& t) override {
    geometry_.upload(c, t);
    if (!htOptionsFor(s.method, s.options).brdfTable) return;
    std::shared_ptr<const BrdfTables> tables = t.ownPtr<BrdfTables>();
    if (tables != brdfTables_) {
      if (tables->perMaterial.size() != c.materialCount)
        throw Error("internal: BRDF tables not prepared for every material");
      std::vector<float> all;
      for (const auto& table : tables->perMaterial) {
        std::vector<float> f = table->flattened();
        if (f.size() != size_t(HT_BRDF_TABLE_FLOATS)) throw Error("internal: BRDF table size differs from the shaders'");
        all.insert(all.end(), f.begin(), f.end());
      }
      brdfBuffer_ = uploadArray(c.ctx, all);
      brdfTables_ = tables;
    }
    c.scene.htBrdfTables = brdfBuffer_.address();
  }

  void prepareScratch(GpuTileContext& c, const RenderSettings&) override {
    const VkDeviceSize tilePixels = VkDeviceSize(c.tileW) * c.tileH;
    static_assert(HT_QUEUE_BYTES == HT_PENDING_SLOTS * sizeof(gpu::GpuHtPending) + HT_LEAF_SLOTS * sizeof(gpu::GpuHtLeaf));
    c.deviceBuffer(pending_, tilePixels * HT_QUEUE_BYTES);
    record_ = c.recordHtSamples;
    // The sample log is read on the host, not filled.
    const VkDeviceSize logBytes = tilePixels * HT_SAMPLE_LOG_SLOTS * sizeof(gpu::GpuHtSample);
    if (record_ && sampleLog_.size() < logBytes) sampleLog_ = vk::Buffer(c.ctx, logBytes, vk::MemoryUse::Readback);
  }

  void bindScratch(const RenderSettings&, gpu::GpuPush& push) const override {
    push.htPending = pending_.address();
    if (record_) {
      const VkDeviceAddress a = sampleLog_.address();
      push.htSampleLog = glm::uvec2(uint32_t(a), uint32_t(a >> 32));
    }
  }

  // The tile's first accepted samples of every pixel, when recorded.
  void readTile(const RenderSettings& s, const gpu::GpuPush& push, const gpu::GpuPixel* px,
                GpuRenderResult& out) override {
    if (!record_) return;
    if (out.htSamples.empty()) out.htSamples.resize(size_t(s.width) * s.height);
    sampleLog_.invalidate();
    const auto* log = static_cast<const gpu::GpuHtSample*>(sampleLog_.mapped());
    for (uint32_t y = 0; y < push.tileHeight; ++y)
      for (uint32_t x = 0; x < push.tileWidth; ++x) {
        const size_t i = size_t(y) * push.tileWidth + x;
        const uint32_t n = std::min<uint32_t>(px[i].directions, HT_SAMPLE_LOG_SLOTS);
        auto& samples = out.htSamples[size_t(push.tileY + y) * s.width + push.tileX + x];
        for (uint32_t k = 0; k < n; ++k) {
          const gpu::GpuHtSample& g = log[i * HT_SAMPLE_LOG_SLOTS + k];
          samples.push_back({g.dir, g.h, uint64_t(g.candidate.x) | uint64_t(g.candidate.y) << 32, int(g.level),
                             g.weight});
        }
      }
  }

 private:
  GpuHtGeometry geometry_;
  std::shared_ptr<const BrdfTables> brdfTables_;
  vk::Buffer brdfBuffer_;
  vk::Buffer pending_;
  bool record_ = false;
  vk::Buffer sampleLog_;
};

}  // namespace

std::unique_ptr<GpuMethodState> makeHtGpuState() { return std::make_unique<HtGpuState>(); }

}  // namespace ht
