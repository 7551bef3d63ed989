// restir* on the Vulkan path: the image's shading points and two sets of
// reservoirs, each for a group of chains, sized to the image at upload.
#include <algorithm>

#include "gpu_method.h"
#include "render.h"
#include "restir.h"
#include "shared.h"

namespace ht {
namespace {

// The reservoirs' share of memory: 96 MiB on a CPU device, an eighth of a
// GPU's.
uint64_t reservoirBudget(const vk::PhysicalDeviceInfo& d) {
  const uint64_t cpu = uint64_t(96) << 20;
  return d.type == VK_PHYSICAL_DEVICE_TYPE_CPU ? cpu : std::max(cpu, d.deviceLocalBytes / 8);
}

class RestirGpuState : public GpuMethodState {
 public:
  void upload(GpuUploadContext& c, const RenderSettings& s, const MethodTables&) override {
    const uint64_t pixels = uint64_t(s.width) * uint64_t(s.height);
    const uint64_t perChain = 2 * pixels * sizeof(gpu::GpuRestirReservoir);
    const uint64_t chains = std::clamp<uint64_t>(reservoirBudget(c.ctx.info) / std::max<uint64_t>(perChain, 1), 1,
                                                 std::min<uint64_t>(HT_RESTIR_MAX_CHAINS, uint64_t(std::max(s.spp, 1))));
    bool fresh = grow(c.ctx, points_, pixels * sizeof(gpu::GpuRestirPoint));
    for (vk::Buffer& b : reservoirs_) fresh = grow(c.ctx, b, chains * pixels * sizeof(gpu::GpuRestirReservoir)) || fresh;
    // lavapipe makes a buffer's pages at their first write: before the clock.
    if (fresh)
      c.ctx.submitAndWait([&](VkCommandBuffer cmd) {
        for (vk::Buffer* b : {&points_, &reservoirs_[0], &reservoirs_[1]})
          c.ctx.fn.vkCmdFillBuffer(cmd, b->handle(), 0, VK_WHOLE_SIZE, 0);
      });
    c.scene.restirPoints = points_.address();
    c.scene.restirReservoirs[0] = reservoirs_[0].address();
    c.scene.restirReservoirs[1] = reservoirs_[1].address();
    const RestirOptions o = restirOptionsFor(s.method, s.options);
    c.scene.restirChains = uint32_t(chains);
    c.scene.restirNeighbours = uint32_t(o.neighbours);
    c.scene.restirRadius = uint32_t(o.radius);
    c.scene.restirRounds = uint32_t(o.rounds);
  }

 private:
  static bool grow(vk::Context& ctx, vk::Buffer& b, uint64_t bytes) {
    if (b.size() >= bytes) return false;
    b = vk::Buffer(ctx, std::max<uint64_t>(bytes, 4), vk::MemoryUse::DeviceLocal);
    return true;
  }
  vk::Buffer points_;         // GpuRestirPoint per pixel
  vk::Buffer reservoirs_[2];  // GpuRestirReservoir per chain of a group and pixel
};

}  // namespace

std::unique_ptr<GpuMethodState> makeRestirGpuState() { return std::make_unique<RestirGpuState>(); }

}  // namespace ht
