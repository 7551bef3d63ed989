// ht-cut on the Vulkan path: HT's node geometry, and per cut the records
// of the nodes its loop weighs, the lookup and the records of the tree's
// nodes the descent weighs (GpuScene::cut*), through texel views where the
// scene has them.
#include <algorithm>
#include <cmath>

#include "gpu_method.h"
#include "ht.h"
#include "ht_cut.h"
#include "render.h"
#include "shared.h"
#include "tables.h"

namespace ht {
namespace {

using namespace ht::gpu;

class CutGpuState : public GpuMethodState {
 public:
  void upload(GpuUploadContext& c, const RenderSettings& s, const MethodTables& t) override {
    const HtGeometry& g = t.geometry();
    geometry_.upload(c, t);
    std::shared_ptr<const EnvCut> cutPtr = t.ownPtr<EnvCut>();
    const EnvCut& cut = *cutPtr;
    const CutOptions options = cutOptionsFor(s.options);
    const int treeLevel = std::clamp(options.productLevel, 0, cut.momentLevel);
    if (cut_ != cutPtr || treeLevel_ != treeLevel) {
      // The records the loop over the cut reads (GpuScene::cutRecord): its
      // K nodes, then each one's four children, CutPoint's lights with their
      // levels' constants.
      const size_t K = cut.nodes.size();
      std::vector<glm::vec4> records(4 * 5 * K, glm::vec4(0.0f));
      auto record = [&](size_t r, uint64_t at, const glm::vec3& chroma) {
        const CutLight& n = cut.lights[r];
        const size_t l = size_t(n.level);
        records[4 * r + 0] = glm::vec4(n.centre, cut.discSin[l]);
        records[4 * r + 1] = glm::vec4(n.moment, n.power);
        records[4 * r + 2] = glm::vec4(chroma, g.levelCosRadius[l]);
        records[4 * r + 3] = glm::vec4(g.levelSinRadius[l], cut.discChord[l], float(n.level), float(at));
      };
      for (size_t k = 0; k < K; ++k) {
        const CutNode& n = cut.nodes[k];
        record(k, MaxAvgTree::levelOffset(n.level) + n.node, n.chroma);
        if (n.level < cut.momentLevel)
          for (uint64_t j = 0; j < 4; ++j)
            record(K + 4 * k + j, MaxAvgTree::levelOffset(n.level + 1) + 4 * n.node + j, glm::vec3(0.0f));
      }
      // The descent's nodes (GpuScene::cutTree): each one's CutLight and
      // chroma in three texels, so that a child costs three fetches.
      const MaxAvgTree& tree = c.hostScene.environment.tree;
      std::vector<glm::vec4> nodes(3 * size_t(MaxAvgTree::levelOffset(treeLevel + 1)));
      for (int level = 0; level <= treeLevel; ++level)
        for (uint64_t i = 0; i < MaxAvgTree::levelSize(level); ++i) {
          const uint64_t at = MaxAvgTree::levelOffset(level) + i;
          const CutLight n = cut.light(tree, g, level, at);
          nodes[3 * at] = glm::vec4(n.centre, n.power);
          nodes[3 * at + 1] = glm::vec4(n.moment, 0.0f);
          nodes[3 * at + 2] = glm::vec4(cut.chroma[at], 0.0f);
        }
      tree_ = uploadArray(c.ctx, nodes);
      record_ = uploadArray(c.ctx, records);
      lookup_ = uploadArray(c.ctx, cut.lookup);
      cut_ = cutPtr;
      treeLevel_ = treeLevel;
    }
    GpuScene& gs = c.scene;
    gs.cutTree = tree_.address();
    gs.cutRecord = record_.address();
    gs.cutLookup = lookup_.address();
    gs.cutCount = uint32_t(cut.nodes.size());
    gs.cutLookupLevel = uint32_t(cut.lookupLevel);
    gs.cutMomentLevel = uint32_t(cut.momentLevel);
    gs.cutProductLevel = uint32_t(std::max(options.productLevel, 0));
    gs.cutFlags = (options.visibility ? HT_CUT_VISIBILITY : 0u) | (options.colourControl ? HT_CUT_COLOUR_CONTROL : 0u);
    gs.cutLobeSpan = cutLobeSpan(options, cut, g);
    gs.cutMinPartial = options.minPartialVisibility;
    gs.cutCapCosMargin = std::cos(kCapMargin);
    gs.cutCapSinMargin = std::sin(kCapMargin);
    std::copy(cut.discSin.begin(), cut.discSin.end(), gs.cutDiscSin);
    std::copy(cut.discChord.begin(), cut.discChord.end(), gs.cutDiscChord);
    std::copy(cut.omega.begin(), cut.omega.end(), gs.cutOmega);
    std::copy(g.levelCosRadius.begin(), g.levelCosRadius.end(), gs.cutLevelCos);
    std::copy(g.levelSinRadius.begin(), g.levelSinRadius.end(), gs.cutLevelSin);
    c.texels[HT_BINDING_CUT_TREE_TEXELS].buffer = &tree_;
    c.texels[HT_BINDING_CUT_RECORD_TEXELS].buffer = &record_;
    c.texels[HT_BINDING_CUT_LOOKUP_TEXELS].buffer = &lookup_;
  }

 private:
  GpuHtGeometry geometry_;
  std::shared_ptr<const EnvCut> cut_;
  int treeLevel_ = -1;
  vk::Buffer tree_, record_, lookup_;
};

}  // namespace

std::unique_ptr<GpuMethodState> makeCutGpuState() { return std::make_unique<CutGpuState>(); }

}  // namespace ht
