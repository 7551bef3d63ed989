// wis, tsis and ris on the Vulkan path: tsis's summed-area table in
// doubles, and per tile pixel the scratch of tsis's regions and of wis's
// exact levels.
#include "gpu_method.h"
#include "render.h"
#include "shared.h"
#include "tables.h"
#include "tsis.h"

namespace ht {
namespace {

bool isWis(Method m) { return m == Method::Wis || m == Method::WisBiased; }

class CompetitorGpuState : public GpuMethodState {
 public:
  void upload(GpuUploadContext& c, const RenderSettings& s, const MethodTables& t) override {
    if (s.method != Method::Tsis || c.scene.envHasLight == 0) return;
    std::shared_ptr<const TsisTable> sat = t.ownPtr<TsisTable>();
    if (sat != tsis_) {
      tsisBuffer_ = vk::Buffer(c.ctx, sat->sat.size() * sizeof(double), vk::MemoryUse::DeviceLocal);
      tsisBuffer_.upload(sat->sat.data(), sat->sat.size() * sizeof(double));
      tsis_ = sat;
    }
    c.scene.tsisSat = tsisBuffer_.address();
    c.scene.tsisLevel = uint32_t(tsis_->level);
  }

  void prepareScratch(GpuTileContext& c, const RenderSettings& s) override {
    const VkDeviceSize tilePixels = VkDeviceSize(c.tileW) * c.tileH;
    if (s.method == Method::Tsis) c.deviceBuffer(tsisScratch_, tilePixels * HT_TSIS_REGIONS * sizeof(gpu::GpuTsisSlot));
    if (isWis(s.method)) c.deviceBuffer(wisScratch_, tilePixels * HT_WIS_TOP_NODES * sizeof(double));
  }

  void bindScratch(const RenderSettings& s, gpu::GpuPush& push) const override {
    push.tsisScratch = s.method == Method::Tsis ? tsisScratch_.address() : 0;
    push.wisScratch = isWis(s.method) ? wisScratch_.address() : 0;
  }

 private:
  std::shared_ptr<const TsisTable> tsis_;
  vk::Buffer tsisBuffer_;
  vk::Buffer tsisScratch_;  // GpuTsisSlot per region and tile pixel
  vk::Buffer wisScratch_;   // HT_WIS_TOP_NODES doubles per tile pixel
};

}  // namespace

std::unique_ptr<GpuMethodState> makeCompetitorGpuState() { return std::make_unique<CompetitorGpuState>(); }

}  // namespace ht
