// mis-compensated on the Vulkan path: its environment technique descends
// its own tree, in the map's tree's place (GpuScene::treeAvg and its texel
// view) while it renders.
#include <algorithm>

#include "gpu_method.h"
#include "shared.h"
#include "tables.h"
#include "tree.h"

namespace ht {
namespace {

class CompensatedGpuState : public GpuMethodState {
 public:
  void upload(GpuUploadContext& c, const RenderSettings&, const MethodTables& t) override {
    std::shared_ptr<const MaxAvgTree> tree = t.ownPtr<MaxAvgTree>();
    if (tree != uploaded_) {
      buffers_.clear();
      std::fill(std::begin(treeAvg_), std::end(treeAvg_), uint64_t(0));
      uploadChunked(c.ctx, tree->avgv.data(), tree->avgv.size(), sizeof(float), gpu::kTreeChunkElements, buffers_,
                    treeAvg_, "mis-compensated tree");
      uploaded_ = tree;
    }
    std::copy(std::begin(treeAvg_), std::end(treeAvg_), c.scene.treeAvg);
    c.scene.envHasLight = uploaded_->total() > 0.0 ? 1u : 0u;
    c.texels[HT_BINDING_TREE_AVG_TEXELS].buffer = &buffers_[0];
  }

 private:
  std::shared_ptr<const MaxAvgTree> uploaded_;
  std::vector<vk::Buffer> buffers_;
  uint64_t treeAvg_[HT_MAX_CHUNKS] = {};
};

}  // namespace

std::unique_ptr<GpuMethodState> makeCompensatedGpuState() { return std::make_unique<CompensatedGpuState>(); }

}  // namespace ht
