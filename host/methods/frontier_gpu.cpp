// ht-frontier on the Vulkan path: HT's node geometry, the colour bins,
// chroma and centroids of the map's nodes, and per render its settings
// (GpuFrontierScene), the shared Lambert table of each side of each plane
// and the layout of a pixel's scratch.
#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "error.h"
#include "gpu_method.h"
#include "ht.h"
#include "ht_frontier.h"
#include "integrator.h"
#include "render.h"
#include "shared.h"
#include "tables.h"

namespace ht {
namespace {

using namespace ht::gpu;

static_assert(FrontierTable::kSegments == HT_FRONTIER_SEGMENTS && kFrontierColourBins * 12 == HT_FRONTIER_SEGMENTS);
static_assert(kFrontierLobeLevel == HT_FRONTIER_LOBE_LEVEL);
static_assert(kFrontierMixtureMin == HT_FRONTIER_MIXTURE_MIN);
static_assert(kFrontierLobeRadii == HT_FRONTIER_LOBE_RADII);
static_assert(kFrontierShareLevel == HT_FRONTIER_SHARE_LEVEL);

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

class FrontierGpuState : public GpuMethodState {
 public:
  // ht-frontier's GpuFrontierScene for this render: frontierOptionsFor's
  // options, the shared Lambert table of each side of each
  // plane, and the layout of a pixel's scratch.
  void upload(GpuUploadContext& c, const RenderSettings& s, const MethodTables& t) override {
    const Scene& hs = c.hostScene;
    const Environment& env = hs.environment;
    const HtGeometry& g = t.geometry();
    std::shared_ptr<const FrontierColours> coloursPtr = t.ownPtr<FrontierColours>();
    const FrontierColours& colours = *coloursPtr;
    const std::vector<uint8_t>& bins = colours.bins;
    const FrontierOptions options = frontierOptionsFor(s.options);
    const int n = std::max(s.spp, 1);
    const bool fp64 = c.fp64;
    vk::Context& ctx = c.ctx;
    geometry_.upload(c, t);
    if (colours_ != coloursPtr) {
      std::vector<uint32_t> packed((bins.size() + 3) / 4, 0u);
      for (size_t i = 0; i < bins.size(); ++i) packed[i / 4] |= uint32_t(bins[i]) << (8 * (i % 4));
      binsBuffer_ = uploadArray(ctx, packed);
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
      upload(colours.chroma, chromaBuffers_, chroma_, "ht-frontier chroma");
      upload(colours.centroid, centroidBuffers_, centroid_, "ht-frontier centroids");
      colours_ = coloursPtr;
    }
    c.texels[HT_BINDING_FRONTIER_CHROMA_TEXELS].buffer = &chromaBuffers_[0];
    c.texels[HT_BINDING_FRONTIER_CENTROID_TEXELS].buffer = &centroidBuffers_[0];
    c.texels[HT_BINDING_FRONTIER_BINS_TEXELS].buffer = &binsBuffer_;
    GpuFrontierScene& f = frontier_;
    f = GpuFrontierScene{};
    f.bins = binsBuffer_.address();
    std::copy(std::begin(chroma_), std::end(chroma_), f.chroma);
    std::copy(std::begin(centroid_), std::end(centroid_), f.centroids);
  
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
    buffers_.clear();
    buffers_.push_back(uploadArray(ctx, headers));
    buffers_.push_back(uploadArray(ctx, nodes));
    buffers_.push_back(uploadArray(ctx, order));
    buffers_.push_back(reals(mass));
    buffers_.push_back(reals(cum));
    buffers_.push_back(uploadArray(ctx, colour));
    buffers_.push_back(reals(faceColour));
    f.sharedHeaders = buffers_[0].address();
    f.sharedNodes = buffers_[1].address();
    f.sharedOrder = buffers_[2].address();
    f.sharedMass = buffers_[3].address();
    f.sharedCum = buffers_[4].address();
    f.sharedColour = buffers_[5].address();
    f.sharedFaceColour = buffers_[6].address();
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
    buffers_.push_back(vk::Buffer(ctx, sizeof(GpuFrontierScene), vk::MemoryUse::DeviceLocal));
    buffers_.back().upload(&f, sizeof(f));
    c.scene.frontier = buffers_.back().address();
  }

  uint64_t scratchBytesPerPixel(const RenderSettings&) const override { return frontier_.pixelBytes; }

  // Blocks of HT_FRONTIER_LANES pixels of a tile row.
  void prepareScratch(GpuTileContext& c, const RenderSettings&) override {
    const VkDeviceSize rowBlocks = (c.tileW + HT_FRONTIER_LANES - 1) / HT_FRONTIER_LANES;
    c.deviceBuffer(scratch_, rowBlocks * HT_FRONTIER_LANES * c.tileH * frontier_.pixelBytes);
  }

  void bindScratch(const RenderSettings&, GpuPush& push) const override { push.frontierScratch = scratch_.address(); }

 private:
  GpuHtGeometry geometry_;
  // Per map.
  std::shared_ptr<const FrontierColours> colours_;
  vk::Buffer binsBuffer_;
  std::vector<vk::Buffer> chromaBuffers_, centroidBuffers_;
  uint64_t chroma_[HT_FRONTIER_CHROMA_CHUNKS] = {};
  uint64_t centroid_[HT_FRONTIER_CHROMA_CHUNKS] = {};
  // Per render.
  std::vector<vk::Buffer> buffers_;
  GpuFrontierScene frontier_{};
  vk::Buffer scratch_;  // GpuFrontierScene::pixelBytes per tile pixel, rows in blocks of HT_FRONTIER_LANES
};

}  // namespace

std::unique_ptr<GpuMethodState> makeFrontierGpuState() { return std::make_unique<FrontierGpuState>(); }

}  // namespace ht
