#include "gpu_render.h"

#include <unistd.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>

#include <fmt/format.h>
#include <glm/geometric.hpp>

#include "common.h"  // shaders/common.h
#include "brdf_table.h"
#include "error.h"
#include "healpix.h"
#include "ht.h"
#include "ht_frontier.h"
#include "sampling.h"
#include "tsis.h"
#include "wis.h"
#include "vk/buffers.h"
#include "vk/device.h"
#include "vk/pipeline.h"

namespace ht {
namespace {

using namespace ht::gpu;

// Directions per dispatch: bounds the time of one dispatch (about 1 s on
// lavapipe with 2 cores for mis); a GPU takes 16 times more, so that a
// tile has pixels enough to fill it.
uint64_t directionsPerDispatch(const vk::PhysicalDeviceInfo& d) {
  return d.type == VK_PHYSICAL_DEVICE_TYPE_CPU ? uint64_t(1) << 22 : uint64_t(1) << 26;
}
// ht-frontier: the tile's scratch (its pixels' tables) at most, on a CPU
// device (where a larger tile gains nothing) and on a GPU: an eighth of its
// memory, so that a tile fills the GPU with enough pixels.
constexpr uint64_t kCpuScratchBytes = uint64_t(96) << 20;
uint64_t scratchBudget(const vk::PhysicalDeviceInfo& d) {
  if (d.type == VK_PHYSICAL_DEVICE_TYPE_CPU) return kCpuScratchBytes;
  return std::max(kCpuScratchBytes, d.deviceLocalBytes / 8);
}

static_assert(BrdfTable::kMargin == float(HT_BRDF_TABLE_MARGIN));
static_assert(uint32_t(SamplerKind::Independent) == HT_SAMPLER_INDEPENDENT &&
              uint32_t(SamplerKind::Stratified) == HT_SAMPLER_STRATIFIED);
static_assert(FrontierTable::kSegments == HT_FRONTIER_SEGMENTS && kFrontierColourBins * 12 == HT_FRONTIER_SEGMENTS);
static_assert(int(Method::HtFrontier) == HT_METHOD_HT_FRONTIER);
static_assert(kFrontierLobeLevel == HT_FRONTIER_LOBE_LEVEL);
static_assert(kFrontierMixtureMin == HT_FRONTIER_MIXTURE_MIN);
static_assert(kFrontierLobeRadii == HT_FRONTIER_LOBE_RADII);
static_assert(kFrontierShareLevel == HT_FRONTIER_SHARE_LEVEL);
static_assert(TsisPoint::kDefaultRegions == HT_TSIS_REGIONS && TsisTable::kMaxLevel == HT_TSIS_MAX_LEVEL);
static_assert(WisPoint::kExactLevels == HT_WIS_EXACT_LEVELS && WisPoint::kMaxOrder == HT_WIS_MAX_ORDER &&
              MaxAvgTree::levelOffset(HT_WIS_EXACT_LEVELS + 1) == HT_WIS_TOP_NODES);
// The largest summed-area table fits one buffer (GpuScene::tsisSat).
static_assert(12ull * ((1ull << HT_TSIS_MAX_LEVEL) + 1) * ((1ull << HT_TSIS_MAX_LEVEL) + 1) * sizeof(double) <=
              (96ull << 20));
static_assert(int(MaterialType::Lambert) == HT_MATERIAL_LAMBERT && int(MaterialType::Phong) == HT_MATERIAL_PHONG &&
              int(MaterialType::Ggx) == HT_MATERIAL_GGX);

// A uniform block: within every device's maxUniformBufferRange (at least 16 KiB).
static_assert(sizeof(GpuScene) <= 16384);

constexpr vk::BindingLayout kBindings[] = {
    {HT_BINDING_SCENE, sizeof(GpuScene), 0, vk::BindingKind::Uniform},
    {HT_BINDING_MATERIALS, 0, sizeof(GpuMaterial)},
    {HT_BINDING_SPHERES, 0, sizeof(GpuSphere)},
    {HT_BINDING_PLANES, 0, sizeof(GpuPlane)},
    {HT_BINDING_PIXELS, 0, sizeof(GpuPixel)},
    {HT_BINDING_RADIANCE_TEXELS, 0, 0, vk::BindingKind::UniformTexel},
    {HT_BINDING_TREE_AVG_TEXELS, 0, 0, vk::BindingKind::UniformTexel},
    {HT_BINDING_TREE_MAX_TEXELS, 0, 0, vk::BindingKind::UniformTexel},
    {HT_BINDING_HT_CENTERS_TEXELS, 0, 0, vk::BindingKind::UniformTexel},
    {HT_BINDING_HT_CONES_TEXELS, 0, 0, vk::BindingKind::UniformTexel},
    {HT_BINDING_FRONTIER_CHROMA_TEXELS, 0, 0, vk::BindingKind::UniformTexel},
    {HT_BINDING_FRONTIER_CENTROID_TEXELS, 0, 0, vk::BindingKind::UniformTexel},
    {HT_BINDING_FRONTIER_BINS_TEXELS, 0, 0, vk::BindingKind::UniformTexel},
};
static_assert(std::size(kBindings) == HT_BINDING_COUNT);

GpuDeviceInfo toInfo(const vk::PhysicalDeviceInfo& d) {
  GpuDeviceInfo g;
  g.index = d.index;
  g.name = d.name;
  g.type = d.typeName;
  g.driver = d.driverInfo.empty() ? d.driverName : d.driverName + " " + d.driverInfo;
  g.apiVersion = d.apiVersionString;
  g.usable = d.usable;
  g.unusableReason = d.unusableReason;
  g.shaderFloat64 = d.shaderFloat64;
  g.timestamps = d.timestampValidBits > 0;
  g.timestampPeriodNs = d.timestampPeriodNs;
  g.maxStorageBufferRange = d.maxStorageBufferRange;
  g.maxPushConstantsSize = d.maxPushConstantsSize;
  g.subgroupSize = d.subgroupSize;
  g.deviceLocalBytes = d.deviceLocalBytes;
  return g;
}

// Uploads `count` elements of `elementSize` bytes in chunks of
// `chunkElements`, each its own buffer; writes their addresses.
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

// A storage buffer holding `items` (at least one element, so that it exists).
template <typename T>
vk::Buffer uploadArray(vk::Context& ctx, const std::vector<T>& items) {
  vk::Buffer b(ctx, std::max<size_t>(items.size(), 1) * sizeof(T), vk::MemoryUse::DeviceLocal);
  b.upload(items.data(), items.size() * sizeof(T));
  return b;
}

// Loop iterations one pixel may spend in one dispatch, a quarter of what
// llvmpipe allows an invocation in all (GpuPixelState).
constexpr uint64_t kLoopIterationsPerBatch = 16384;
// Batches a submission holds, at most.
constexpr uint64_t kBatchesPerSubmission = 64;

// Samples (ht*: traversal steps) per pixel and dispatch, from a rough count
// of the loop iterations each costs. Only the first guess: a dispatch whose
// loops were cut short makes the renderer halve it and start the tile again.
uint32_t firstBatchLimit(const RenderSettings& s, int envOrder, size_t shapes) {
  const uint64_t spp = uint64_t(std::max(s.spp, 1));
  const uint64_t descent = uint64_t(envOrder) + 4 + shapes;  // one environment sample and its shadow ray
  uint64_t cost = descent;
  switch (s.method) {
    case Method::Mis: cost = 2 * descent; break;
    case Method::Ris: cost = uint64_t(std::max(s.options.risCandidates, 1)) * descent + shapes; break;
    case Method::Tsis: cost = 2 * HT_TSIS_REGIONS + 4 * descent; break;
    case Method::Wis:
    case Method::WisBiased: {
      const int order = std::clamp(s.options.wisOrder, 0, std::min(envOrder, HT_WIS_MAX_ORDER));
      cost = 12 + 4 * uint64_t(order) + descent;
      if (s.method == Method::WisBiased) cost += uint64_t(1) << (2 * (envOrder - order));
      break;
    }
    case Method::Ht:
    case Method::HtVis:
    case Method::HtBiased:
    // A step of the walk is one node: its loop, and the caps' (ht-vis);
    // its share of the leaves' visible fractions and of the samples' shading
    // grows with the samples per pixel (measured, ht-vis on spheres.json at
    // 96x48: the longest batch within llvmpipe's loop limit was 4096 steps at
    // 64 spp, 1024 at 256, 512 at 1024).
    case Method::HtVisBiased: cost = (4 + 2 * shapes) * std::max<uint64_t>(1, spp / 64); break;
    // Per direction a descent of four children a level, each under the
    // caps, and a few binary searches.
    case Method::HtFrontier: cost = uint64_t(envOrder) * (4 + 4 * shapes) + 40 + descent; break;
    default: break;
  }
  return uint32_t(std::clamp<uint64_t>(kLoopIterationsPerBatch / cost, 1, 1u << 20));
}

// The compute shader of a method's family (shaders/<name>.comp.glsl).
const char* familyShader(Family f) {
  switch (f) {
    case Family::Baseline: return "baselines";
    case Family::Ht: return "ht";
    case Family::Competitor: return "competitors";
    case Family::Product: return "frontier";
    default: return nullptr;
  }
}

}  // namespace

std::vector<GpuDeviceInfo> listGpuDevices() {
  std::vector<GpuDeviceInfo> list;
  for (const vk::PhysicalDeviceInfo& d : vk::listPhysicalDevices()) list.push_back(toInfo(d));
  return list;
}

int defaultGpuDevice(const std::vector<GpuDeviceInfo>& devices) {
  auto rank = [](const std::string& t) {
    return t == "discrete" ? 4 : t == "integrated" ? 3 : t == "virtual" ? 2 : t == "cpu" ? 1 : 0;
  };
  int best = -1;
  for (const GpuDeviceInfo& d : devices)
    if (d.usable && (best < 0 || rank(d.type) > rank(devices[best].type))) best = int(d.index);
  return best;
}

bool gpuSupportsMethod(Method m) { return methodInfo(m).gpu && familyShader(methodInfo(m).family); }

std::string gpuSceneLimit(Method method, size_t occluders) {
  const MethodInfo& info = methodInfo(method);
  if ((info.family == Family::Ht || method == Method::HtFrontier) && info.visibility && occluders > HT_MAX_CAPS)
    return fmt::format("method {} on the GPU handles at most {} spheres and planes (the scene has {}); "
                       "use --device cpu", methodName(method), HT_MAX_CAPS, occluders);
  return {};
}

std::string shaderDirNextToExecutable() {
  std::error_code ec;
  std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return "shaders";
  return (exe.parent_path() / "shaders").string();
}

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
  void bindScratch(const RenderSettings& s, GpuPush& push) const;
  std::pair<double, double> submitBatches(GpuPush& push, uint32_t first, uint32_t count, uint32_t limit);
  void warmPipeline(const RenderSettings& s);
  void renderTile(const RenderSettings& s, GpuPush& push, uint32_t& limit, GpuRenderResult& out);
  void readTile(const RenderSettings& s, const GpuPush& push, GpuRenderResult& out);

  explicit Impl(const GpuOptions& o)
      : ctx(vk::ContextOptions{o.deviceIndex, o.validation, o.precision != GpuPrecision::Fp32, o.validationLog}),
        precision(o.precision) {
    info = toInfo(ctx.info);
    recordHtSamples = o.recordHtSamples;
    batchLimit = o.batchLimit;
    texelViews = o.texelViews;
    maxTileSide = std::max<uint32_t>(kWorkgroupSize, uint32_t(std::max(o.maxTileSide, 1)) / kWorkgroupSize * kWorkgroupSize);
    shaderDir = o.shaderDir.empty() ? shaderDirNextToExecutable() : o.shaderDir;
    // Checks a shader against the host now; the cheapest method's pipeline,
    // as compiling takes long on lavapipe.
    usePipeline(Method::Uniform, false);
    if (ctx.info.timestampValidBits > 0) {
      VkQueryPoolCreateInfo q{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
      q.queryType = VK_QUERY_TYPE_TIMESTAMP;
      q.queryCount = 3;
      vk::check(ctx.fn.vkCreateQueryPool(ctx.device, &q, nullptr, &queries), "vkCreateQueryPool");
      timestampMask = ctx.info.timestampValidBits >= 64 ? ~uint64_t(0)
                                                        : (uint64_t(1) << ctx.info.timestampValidBits) - 1;
    }
  }
  // The method's family shader specialized for it (HT_SPEC_METHOD) and for
  // whether HT's BRDF bounds are tabulated, with the buffers bound so far
  // bound again.
  void usePipeline(Method method, bool brdfTable) {
    const uint32_t capSlots = uint32_t(std::min<size_t>(occluders, HT_MAX_CAPS));
    if (pipelineMethod == uint32_t(method) && pipelineTexels == texels && pipelineCapSlots == capSlots &&
        pipelineBrdfTable == brdfTable)
      return;
    const uint32_t specialization[] = {uint32_t(method), texels ? 1u : 0u, capSlots, brdfTable ? 1u : 0u};
    shaderName =
        fmt::format("{}.{}.spv", familyShader(methodInfo(method).family), usesFloat64(method) ? "fp64" : "fp32");
    pipeline.emplace(ctx, (std::filesystem::path(shaderDir) / shaderName).string(), kBindings,
                     uint32_t(sizeof(GpuPush)), std::array<uint32_t, 3>{kWorkgroupSize, kWorkgroupSize, 1},
                     specialization);
    pipelineMethod = uint32_t(method);
    pipelineTexels = texels;
    pipelineCapSlots = capSlots;
    pipelineBrdfTable = brdfTable;
    pipelineRan = false;
    if (hasScene) bindScene();
    if (pixels.size() > 0) pipeline->setBuffer(HT_BINDING_PIXELS, pixels);
  }
  // The scene's buffers and texel views (placeholders without kTexels or
  // where an array is not uploaded).
  void bindScene() {
    pipeline->setBuffer(HT_BINDING_SCENE, sceneBuffer);
    pipeline->setBuffer(HT_BINDING_MATERIALS, materials);
    pipeline->setBuffer(HT_BINDING_SPHERES, spheres);
    pipeline->setBuffer(HT_BINDING_PLANES, planes);
    for (auto& [binding, t] : texelBuffers) {
      vk::Buffer* buffer = texels ? t.buffer : nullptr;
      if (!buffer) {
        buffer = &placeholders[t.format];
        if (!buffer->handle()) *buffer = vk::Buffer(ctx, 4, vk::MemoryUse::DeviceLocal);
      }
      pipeline->setTexelBuffer(binding, buffer->texelView(t.format));
    }
  }
  ~Impl() {
    if (ctx.device) ctx.fn.vkDeviceWaitIdle(ctx.device);
    if (queries) ctx.fn.vkDestroyQueryPool(ctx.device, queries, nullptr);
  }
};

GpuRenderer::GpuRenderer(const GpuOptions& options) : impl_(std::make_unique<Impl>(options)) {}
GpuRenderer::~GpuRenderer() = default;

const GpuDeviceInfo& GpuRenderer::device() const { return impl_->info; }
bool GpuRenderer::float64() const { return impl_->ctx.float64; }
std::string GpuRenderer::shaderName() const { return impl_->shaderName; }
bool GpuRenderer::texelViews() const { return impl_->pipelineTexels; }
const vk::ValidationLog& GpuRenderer::validationLog() const { return impl_->ctx.validationLog(); }

void GpuRenderer::setScene(const Scene& scene) {
  Impl& m = *impl_;
  vk::Context& ctx = m.ctx;
  const Environment& env = scene.environment;
  m.hasScene = false;
  m.chunks.clear();

  GpuScene gs{};
  const uint64_t pixelCount = healpix::pixelCount(env.order);
  if (env.radiance.size() != pixelCount || env.tree.avgv.size() != env.tree.maxv.size() ||
      env.tree.avgv.size() < MaxAvgTree::levelOffset(env.order + 1))
    throw Error("internal: environment without its radiance or trees");
  size_t first[3];
  first[0] = m.chunks.size();
  uploadChunked(ctx, env.radiance.data(), pixelCount, sizeof(glm::vec3), kRadianceChunkElements, m.chunks,
                gs.radiance, "environment radiance");
  first[1] = m.chunks.size();
  uploadChunked(ctx, env.tree.avgv.data(), env.tree.avgv.size(), sizeof(float), kTreeChunkElements, m.chunks,
                gs.treeAvg, "environment average tree");
  first[2] = m.chunks.size();
  uploadChunked(ctx, env.tree.maxv.data(), env.tree.maxv.size(), sizeof(float), kTreeChunkElements, m.chunks,
                gs.treeMax, "environment max tree");
  // The HT geometry has one element per tree node.
  const uint64_t nodes = env.tree.maxv.size(), maxTexels = ctx.info.maxTexelBufferElements;
  m.texels = m.texelViews && pixelCount <= kRadianceChunkElements && 3 * pixelCount <= maxTexels &&
             nodes <= kTreeChunkElements && nodes <= (uint64_t(1) << HT_HT_VEC3_CHUNK_SHIFT) &&
             nodes <= (uint64_t(1) << HT_HT_VEC2_CHUNK_SHIFT) && 3 * nodes <= maxTexels;
  for (auto& [binding, t] : m.texelBuffers) t.buffer = nullptr;
  m.texelBuffers[HT_BINDING_RADIANCE_TEXELS].buffer = &m.chunks[first[0]];
  m.texelBuffers[HT_BINDING_TREE_AVG_TEXELS].buffer = &m.chunks[first[1]];
  m.texelBuffers[HT_BINDING_TREE_MAX_TEXELS].buffer = &m.chunks[first[2]];

  // The camera basis exactly as cameraRay (host/scene.cpp) computes it.
  const Camera& c = scene.camera;
  const glm::vec3 w = glm::normalize(c.lookAt - c.position);
  const glm::vec3 u = glm::normalize(glm::cross(w, c.up));
  const glm::vec3 v = glm::cross(u, w);
  gs.camPosition = c.position;
  gs.camW = w;
  gs.camU = u;
  gs.camV = v;
  gs.tanHalfFov = std::tan(0.5f * c.fovY * kPi / 180.0f);
  gs.envOrder = uint32_t(env.order);
  gs.envHasLight = env.hasLight() ? 1u : 0u;
  gs.envCosYaw = env.cosYaw;
  gs.envSinYaw = env.sinYaw;
  const double solidAngle = env.pixelSolidAngle();
  const uint64_t bits = std::bit_cast<uint64_t>(solidAngle);
  gs.envPixelSolidAngleBits = glm::uvec2(uint32_t(bits), uint32_t(bits >> 32));
  gs.envPixelSolidAngle = float(solidAngle);
  gs.sphereCount = uint32_t(scene.spheres.size());
  gs.planeCount = uint32_t(scene.planes.size());
  gs.materialCount = uint32_t(scene.materials.size());
  std::vector<GpuMaterial> materials;
  for (const Material& mat : scene.materials)
    materials.push_back({uint32_t(mat.type), mat.diffuse, mat.specular, mat.exponent, mat.alpha,
                         specularLobeProbability(mat)});
  std::vector<GpuSphere> spheres;
  for (const Sphere& s : scene.spheres) spheres.push_back({s.center, s.radius, uint32_t(s.material)});
  std::vector<GpuPlane> planes;
  for (const Plane& p : scene.planes) planes.push_back({p.point, p.normal, uint32_t(p.material)});

  m.sceneBuffer = vk::Buffer(ctx, sizeof(GpuScene), vk::MemoryUse::DeviceLocal);
  m.sceneBuffer.upload(&gs, sizeof(gs));
  m.materials = uploadArray(ctx, materials);
  m.spheres = uploadArray(ctx, spheres);
  m.planes = uploadArray(ctx, planes);
  m.bindScene();
  m.scene = gs;
  m.envOrder = env.order;
  m.materialCount = scene.materials.size();
  m.occluders = scene.spheres.size() + scene.planes.size();
  m.geometry = nullptr;
  m.geometryBuffers.clear();
  m.brdfTables.clear();
  m.brdfBuffer = {};
  m.tsis = nullptr;
  m.tsisBuffer = {};
  m.frontierColours = nullptr;
  m.frontierBinsBuffer = {};
  m.frontierChromaBuffers.clear();
  m.frontierCentroidBuffers.clear();
  m.frontierBuffers.clear();
  m.hostScene = &scene;
  m.hasScene = true;
}

// The tables the method reads, uploaded at its first render (and again when
// they are other tables), so that the other methods never build them.
void GpuRenderer::Impl::uploadTables(const RenderSettings& s, const MethodTables& t) {
  const MethodInfo& info = methodInfo(s.method);
  bool changed = false;
  if (info.family == Family::Ht || s.method == Method::HtFrontier) {
    if (const std::string limit = gpuSceneLimit(s.method, occluders); !limit.empty()) throw Error(limit);
    if (geometry != t.htGeometry) {
      const HtGeometry& g = t.geometry();
      if (g.order != envOrder) throw Error("internal: HT geometry of another order than the map's");
      geometryBuffers.clear();
      uploadChunked(ctx, g.centers.data(), g.centers.size(), sizeof(glm::vec3),
                    uint64_t(1) << HT_HT_VEC3_CHUNK_SHIFT, geometryBuffers, scene.htCenters, "HT node centres");
      const size_t cones = geometryBuffers.size();
      uploadChunked(ctx, g.cosSinRadius.data(), g.cosSinRadius.size(), sizeof(glm::vec2),
                    uint64_t(1) << HT_HT_VEC2_CHUNK_SHIFT, geometryBuffers, scene.htCosSinRadius, "HT node radii");
      texelBuffers[HT_BINDING_HT_CENTERS_TEXELS].buffer = &geometryBuffers[0];
      texelBuffers[HT_BINDING_HT_CONES_TEXELS].buffer = &geometryBuffers[cones];
      static_assert(sizeof(scene.htLevelRadius) == sizeof(g.levelRadius));
      std::copy(g.levelRadius.begin(), g.levelRadius.end(), scene.htLevelRadius);
      geometry = t.htGeometry;
      changed = true;
    }
    if (info.family == Family::Ht && s.options.brdfBounds == MethodOptions::BrdfBounds::Table &&
        brdfTables != t.brdfTables) {
      if (t.brdfTables.size() != materialCount) throw Error("internal: BRDF tables not prepared for every material");
      std::vector<float> all;
      for (const auto& table : t.brdfTables) {
        std::vector<float> f = table->flattened();
        if (f.size() != size_t(HT_BRDF_TABLE_FLOATS)) throw Error("internal: BRDF table size differs from the shaders'");
        all.insert(all.end(), f.begin(), f.end());
      }
      brdfBuffer = uploadArray(ctx, all);
      scene.htBrdfTables = brdfBuffer.address();
      brdfTables = t.brdfTables;
      changed = true;
    }
  }
  // tsis: its summed-area table, in doubles.
  if (s.method == Method::Tsis && scene.envHasLight != 0 && tsis != t.tsisTable()) {
    const TsisTable& sat = *t.tsisTable();
    tsisBuffer = vk::Buffer(ctx, sat.sat.size() * sizeof(double), vk::MemoryUse::DeviceLocal);
    tsisBuffer.upload(sat.sat.data(), sat.sat.size() * sizeof(double));
    scene.tsisSat = tsisBuffer.address();
    scene.tsisLevel = uint32_t(sat.level);
    tsis = t.tsis;
    changed = true;
  }
  if (s.method == Method::HtFrontier) {
    uploadFrontier(s, t);
    changed = true;
  }
  if (changed) {
    sceneBuffer.upload(&scene, sizeof(scene));
    bindScene();
  }
}

namespace {

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

}  // namespace

// ht-frontier's GpuFrontierScene for this render: FrontierOptions as
// estimateDirect sets them, the shared Lambert table of each side of each
// plane, and the layout of a pixel's scratch.
void GpuRenderer::Impl::uploadFrontier(const RenderSettings& s, const MethodTables& t) {
  const Scene& hs = *hostScene;
  const Environment& env = hs.environment;
  const HtGeometry& g = t.geometry();
  const FrontierColours& colours = t.colours();
  const std::vector<uint8_t>& bins = colours.bins;
  FrontierOptions options;
  options.refinements = s.options.frontierRefinements;
  options.colourControl = s.options.frontierColourControl;
  const int n = std::max(s.spp, 1);
  const bool fp64 = usesFloat64(s.method);
  if (frontierColours != t.frontierColours) {
    std::vector<uint32_t> packed((bins.size() + 3) / 4, 0u);
    for (size_t i = 0; i < bins.size(); ++i) packed[i / 4] |= uint32_t(bins[i]) << (8 * (i % 4));
    frontierBinsBuffer = uploadArray(ctx, packed);
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
    upload(colours.chroma, frontierChromaBuffers, frontierChroma, "ht-frontier chroma");
    upload(colours.centroid, frontierCentroidBuffers, frontierCentroid, "ht-frontier centroids");
    frontierColours = t.frontierColours;
    texelBuffers[HT_BINDING_FRONTIER_CHROMA_TEXELS].buffer = &frontierChromaBuffers[0];
    texelBuffers[HT_BINDING_FRONTIER_CENTROID_TEXELS].buffer = &frontierCentroidBuffers[0];
    texelBuffers[HT_BINDING_FRONTIER_BINS_TEXELS].buffer = &frontierBinsBuffer;
  }
  GpuFrontierScene& f = frontier;
  f = GpuFrontierScene{};
  f.bins = frontierBinsBuffer.address();
  std::copy(std::begin(frontierChroma), std::end(frontierChroma), f.chroma);
  std::copy(std::begin(frontierCentroid), std::end(frontierCentroid), f.centroids);

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
  frontierBuffers.clear();
  frontierBuffers.push_back(uploadArray(ctx, headers));
  frontierBuffers.push_back(uploadArray(ctx, nodes));
  frontierBuffers.push_back(uploadArray(ctx, order));
  frontierBuffers.push_back(reals(mass));
  frontierBuffers.push_back(reals(cum));
  frontierBuffers.push_back(uploadArray(ctx, colour));
  frontierBuffers.push_back(reals(faceColour));
  f.sharedHeaders = frontierBuffers[0].address();
  f.sharedNodes = frontierBuffers[1].address();
  f.sharedOrder = frontierBuffers[2].address();
  f.sharedMass = frontierBuffers[3].address();
  f.sharedCum = frontierBuffers[4].address();
  f.sharedColour = frontierBuffers[5].address();
  f.sharedFaceColour = frontierBuffers[6].address();
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
  frontierBuffers.push_back(vk::Buffer(ctx, sizeof(GpuFrontierScene), vk::MemoryUse::DeviceLocal));
  frontierBuffers.back().upload(&f, sizeof(f));
  scene.frontier = frontierBuffers.back().address();
}

namespace {

// A tile's push constants, batch fields aside.
GpuPush tilePush(const RenderSettings& s, uint32_t x, uint32_t y, uint32_t tileW, uint32_t tileH) {
  GpuPush push{};
  push.width = uint32_t(s.width);
  push.height = uint32_t(s.height);
  push.tileX = x;
  push.tileY = y;
  push.tileWidth = std::min(tileW, uint32_t(s.width) - x);
  push.tileHeight = std::min(tileH, uint32_t(s.height) - y);
  push.method = uint32_t(s.method);
  push.spp = uint32_t(std::max(s.spp, 1));
  push.seed = s.seed;
  if (methodInfo(s.method).family == Family::Ht) {
    // HtOptions as estimateDirect (host/integrator.cpp) sets them.
    const HtOptions ho = htOptionsFor(s.method, s.options);
    if (ho.budgetRefinements > HT_MAX_BUDGET_REFINEMENTS || ho.maxLevel > HT_MAX_WALK_LEVEL)
      throw Error("internal: HtOptions beyond the shaders' limits");
    push.htFlags = (ho.visibility ? HT_FLAG_VISIBILITY : 0u) | (ho.biased ? HT_FLAG_BIASED : 0u) |
                   (ho.brdfTable ? HT_FLAG_BRDF_TABLE : 0u) | (ho.sphereSequence ? HT_FLAG_SPHERE_SEQUENCE : 0u) |
                   uint32_t(ho.budgetRefinements) << 8 | uint32_t(ho.maxLevel) << 16;
    push.htBrdfFloor = ho.brdfFloor;
    push.htVisibilityFloor = ho.visibilityFloor;
    push.htBiasedSmoothness = ho.biasedSmoothness;
  }
  push.risCandidates = uint32_t(std::max(s.options.risCandidates, 1));
  push.wisOrder = uint32_t(std::max(s.options.wisOrder, 0));
  push.samplerKind = uint32_t(s.options.sampler);
  push.canaryLoops = 2;
  push.canaryZero = 0;
  return push;
}

// HT's BRDF bounds come from tables (HtOptions::brdfTable).
bool usesBrdfTable(const RenderSettings& s) {
  return methodInfo(s.method).family == Family::Ht && htOptionsFor(s.method, s.options).brdfTable;
}

// Directions a pixel draws, roughly: ris draws M candidates per sample;
// tsis first partitions the sphere (about five BRDF evaluations per region);
// wis evaluates the BRDF at every node of its exact levels, then four times
// per level below them.
uint64_t directionsPerPixel(const RenderSettings& s) {
  const uint64_t spp = uint64_t(std::max(s.spp, 1));
  switch (s.method) {
    case Method::Mis: return 2 * spp;
    case Method::Ris: return spp * uint64_t(std::max(s.options.risCandidates, 1));
    case Method::Tsis: return spp + 5 * HT_TSIS_REGIONS;
    case Method::Wis:
    case Method::WisBiased: return 4 * spp * (HT_WIS_MAX_ORDER - HT_WIS_EXACT_LEVELS) + HT_WIS_TOP_NODES;
    default: return spp;
  }
}

}  // namespace

void GpuRenderer::Impl::checkMethod(const RenderSettings& s) const {
  if (!hasScene) throw Error("internal: GpuRenderer::render before setScene");
  if (!gpuSupportsMethod(s.method))
    throw Error(fmt::format("method {} has no GPU version (it runs on the CPU reference only); use --device cpu",
                            methodName(s.method)));
  if (precision == GpuPrecision::Fp64 && !ctx.float64)
    throw Error(fmt::format("--gpu-precision fp64 needs shaderFloat64, which {} lacks", info.name));
  if (methodInfo(s.method).gpuFloat64 && !usesFloat64(s.method))
    throw Error(fmt::format("method {} needs shaderFloat64 on the GPU ({} has none, or --gpu-precision is fp32); "
                            "use --device cpu", methodName(s.method), info.name));
}

// Square tiles, a multiple of the workgroup, sized so that one dispatch
// draws at most directionsPerDispatch directions (ht*: and its pending
// samples take at most 32 MiB); their buffers.
std::pair<uint32_t, uint32_t> GpuRenderer::Impl::prepareTiles(const RenderSettings& s) {
  const bool htMethod = methodInfo(s.method).family == Family::Ht;
  const bool frontierMethod = s.method == Method::HtFrontier;
  uint32_t side = htMethod ? std::min<uint32_t>(maxTileSide, HT_MAX_TILE_SIDE) : maxTileSide;
  while (side > kWorkgroupSize && uint64_t(side) * side * directionsPerPixel(s) > directionsPerDispatch(ctx.info))
    side = std::max(kWorkgroupSize, side / 2 / kWorkgroupSize * kWorkgroupSize);
  while (frontierMethod && side > kWorkgroupSize && uint64_t(side) * side * frontier.pixelBytes > scratchBudget(ctx.info))
    side = std::max(kWorkgroupSize, side / 2 / kWorkgroupSize * kWorkgroupSize);
  const uint32_t tileW = std::min<uint32_t>(side, uint32_t(s.width));
  const uint32_t tileH = std::min<uint32_t>(side, uint32_t(s.height));
  const VkDeviceSize tilePixels = VkDeviceSize(tileW) * tileH;
  // lavapipe's device memory is the process's, its pages made at their first
  // write: a new buffer is filled here, before the render's clock starts, as
  // a GPU's memory is in place once allocated.
  std::vector<vk::Buffer*> fresh;
  auto deviceBuffer = [&](vk::Buffer& b, VkDeviceSize bytes) {
    if (b.size() >= bytes) return false;
    b = vk::Buffer(ctx, bytes, vk::MemoryUse::DeviceLocal);
    fresh.push_back(&b);
    return true;
  };
  if (deviceBuffer(pixels, tilePixels * sizeof(GpuPixel))) {
    pixelsHost = vk::Buffer(ctx, tilePixels * sizeof(GpuPixel), vk::MemoryUse::Readback);
    pipeline->setBuffer(HT_BINDING_PIXELS, pixels);
  }
  deviceBuffer(pixelState, tilePixels * sizeof(GpuPixelState));
  if (s.method == Method::Tsis) deviceBuffer(tsisScratch, tilePixels * HT_TSIS_REGIONS * sizeof(GpuTsisSlot));
  if (s.method == Method::Wis || s.method == Method::WisBiased)
    deviceBuffer(wisScratch, tilePixels * HT_WIS_TOP_NODES * sizeof(double));
  // ht-frontier's scratch: blocks of HT_FRONTIER_LANES pixels of a tile row.
  const VkDeviceSize rowBlocks = (tileW + HT_FRONTIER_LANES - 1) / HT_FRONTIER_LANES;
  if (frontierMethod) deviceBuffer(frontierScratch, rowBlocks * HT_FRONTIER_LANES * tileH * frontier.pixelBytes);
  static_assert(HT_QUEUE_BYTES == HT_PENDING_SLOTS * sizeof(GpuHtPending) + HT_LEAF_SLOTS * sizeof(GpuHtLeaf));
  if (htMethod) deviceBuffer(htPending, tilePixels * HT_QUEUE_BYTES);
  if (!fresh.empty())
    ctx.submitAndWait([&](VkCommandBuffer cmd) {
      for (vk::Buffer* b : fresh) ctx.fn.vkCmdFillBuffer(cmd, b->handle(), 0, VK_WHOLE_SIZE, 0);
    });
  const VkDeviceSize logBytes = tilePixels * HT_SAMPLE_LOG_SLOTS * sizeof(GpuHtSample);
  if (htMethod && recordHtSamples && htSampleLog.size() < logBytes)
    htSampleLog = vk::Buffer(ctx, logBytes, vk::MemoryUse::Readback);
  return {tileW, tileH};
}

// The tile's scratch buffers in its push constants.
void GpuRenderer::Impl::bindScratch(const RenderSettings& s, GpuPush& push) const {
  push.tsisScratch = s.method == Method::Tsis ? tsisScratch.address() : 0;
  push.wisScratch = s.method == Method::Wis || s.method == Method::WisBiased ? wisScratch.address() : 0;
  push.pixelState = pixelState.address();
  if (methodInfo(s.method).family == Family::Ht) push.htPending = htPending.address();
  if (s.method == Method::HtFrontier) push.frontierScratch = frontierScratch.address();
  if (methodInfo(s.method).family == Family::Ht && recordHtSamples) {
    const VkDeviceAddress a = htSampleLog.address();
    push.htSampleLog = glm::uvec2(uint32_t(a), uint32_t(a >> 32));
  }
}

// lavapipe makes a pipeline's machine code (or loads it from its disk
// cache: some 30 ms for ht) at the pipeline's first dispatch, not when it
// is created. A dispatch of no pixels, once the buffers are bound, does it
// before the render, as drivers that compile in vkCreateComputePipelines do.
void GpuRenderer::Impl::warmPipeline(const RenderSettings& s) {
  if (pipelineRan) return;
  GpuPush push = tilePush(s, 0, 0, 0, 0);
  bindScratch(s, push);
  ctx.submitAndWait([&](VkCommandBuffer cmd) { pipeline->dispatch(cmd, &push, 1, 1); });
  pipelineRan = true;
}

// One submission of `count` batches from `first` on and the copy of the
// tile's results to the host; returns the GPU time of the dispatches and of
// the copy (0 without timestamps).
std::pair<double, double> GpuRenderer::Impl::submitBatches(GpuPush& push, uint32_t first, uint32_t count,
                                                           uint32_t limit) {
  const uint32_t groupsX = (push.tileWidth + kWorkgroupSize - 1) / kWorkgroupSize;
  const uint32_t groupsY = (push.tileHeight + kWorkgroupSize - 1) / kWorkgroupSize;
  auto barrier = [this](VkCommandBuffer cmd, VkAccessFlags src, VkAccessFlags dst, VkPipelineStageFlags from,
                    VkPipelineStageFlags to) {
    VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    b.srcAccessMask = src;
    b.dstAccessMask = dst;
    ctx.fn.vkCmdPipelineBarrier(cmd, from, to, 0, 1, &b, 0, nullptr, 0, nullptr);
  };
  ctx.submitAndWait([&](VkCommandBuffer cmd) {
    // Uploads (host writes, staging copies) before the shader reads.
    barrier(cmd, VK_ACCESS_HOST_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT,
            VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT,
            VK_PIPELINE_STAGE_HOST_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
    if (queries) {
      ctx.fn.vkCmdResetQueryPool(cmd, queries, 0, 3);
      ctx.fn.vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, queries, 0);
    }
    for (uint32_t k = 0; k < count; ++k) {
      // Each batch reads the pixel states the previous one wrote.
      if (k > 0)
        barrier(cmd, VK_ACCESS_SHADER_WRITE_BIT, VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT,
                VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
      push.batch = first + k;
      push.batchLimit = limit;
      pipeline->dispatch(cmd, &push, groupsX, groupsY);
    }
    barrier(cmd, VK_ACCESS_SHADER_WRITE_BIT, VK_ACCESS_TRANSFER_READ_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
            VK_PIPELINE_STAGE_TRANSFER_BIT);
    if (queries) ctx.fn.vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, queries, 1);
    VkBufferCopy region{0, 0, VkDeviceSize(push.tileWidth) * push.tileHeight * sizeof(GpuPixel)};
    ctx.fn.vkCmdCopyBuffer(cmd, pixels.handle(), pixelsHost.handle(), 1, &region);
    if (queries) ctx.fn.vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queries, 2);
    barrier(cmd, VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT, VK_ACCESS_HOST_READ_BIT,
            VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT);
  });
  if (!queries) return {0.0, 0.0};
  uint64_t stamps[3];
  vk::check(ctx.fn.vkGetQueryPoolResults(ctx.device, queries, 0, 3, sizeof(stamps), stamps, sizeof(uint64_t),
                                  VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
            "vkGetQueryPoolResults");
  const double tick = double(ctx.info.timestampPeriodNs) * 1e-9;
  return {double((stamps[1] - stamps[0]) & timestampMask) * tick, double((stamps[2] - stamps[1]) & timestampMask) * tick};
}

// Batches until every pixel of the tile is done; the whole tile again with
// smaller batches where the driver cut a loop short.
void GpuRenderer::Impl::renderTile(const RenderSettings& s, GpuPush& push, uint32_t& limit, GpuRenderResult& out) {
  const size_t tilePixels = size_t(push.tileWidth) * push.tileHeight;
  const auto* px = static_cast<const GpuPixel*>(pixelsHost.mapped());
  const uint64_t spp = uint64_t(std::max(s.spp, 1));
  const bool htMethod = methodInfo(s.method).family == Family::Ht;
  for (uint32_t batch = 0;;) {
    // The sampling methods need ceil(spp / limit) batches; HT's traversal
    // takes some 40 steps per sample, read back to see when it is done.
    const uint64_t expected = htMethod ? (40 * spp + 400 + limit - 1) / limit
                                       : (spp + limit - 1) / limit;
    // Past them, half as many again as have run: a finished pixel returns at
    // once from a batch, so the batches after the slowest one cost little.
    const uint64_t wanted = batch < expected ? expected - batch : batch / 2;
    const uint32_t count = uint32_t(std::clamp<uint64_t>(wanted, 1, kBatchesPerSubmission));
    const auto [seconds, readback] = submitBatches(push, batch, count, limit);
    if (queries) {
      out.gpuSeconds += seconds;
      out.readbackSeconds += readback;
    }
    ++out.submissions;
    batch += count;
    pixelsHost.invalidate();
    bool cut = false, done = true;
    for (size_t i = 0; i < tilePixels; ++i) {
      cut = cut || (px[i].status & HT_PIXEL_LOOPS_CUT) != 0;
      done = done && (px[i].status & HT_PIXEL_DONE) != 0;
    }
    if (cut) {
      if (limit == 1)
        throw Error(fmt::format("the Vulkan driver of {} ended a shader loop early even at one sample per "
                                "dispatch; use --device cpu", info.name));
      limit /= 2;
      batch = 0;
      ++out.restarts;
      continue;
    }
    if (done) return;
  }
}

// The finished tile's pixels, counters and (ht*, when asked) first samples.
void GpuRenderer::Impl::readTile(const RenderSettings& s, const GpuPush& push, GpuRenderResult& out) {
  RenderResult& r = out.result;
  const auto* px = static_cast<const GpuPixel*>(pixelsHost.mapped());
  for (uint32_t y = 0; y < push.tileHeight; ++y)
    for (uint32_t x = 0; x < push.tileWidth; ++x) {
      const GpuPixel& p = px[size_t(y) * push.tileWidth + x];
      r.image.at(int(push.tileX + x), int(push.tileY + y)) = p.radiance;
      r.shadedPixels += p.shaded;
      r.counters.directions += p.directions;
      r.counters.shadowRays += p.shadowRays;
      r.counters.htNodes += p.htNodes;
      if (s.pixelCounts) r.pixelDirections[size_t(push.tileY + y) * s.width + push.tileX + x] = p.directions;
    }
  if (methodInfo(s.method).family != Family::Ht || !recordHtSamples) return;
  if (out.htSamples.empty()) out.htSamples.resize(size_t(s.width) * s.height);
  htSampleLog.invalidate();
  const auto* log = static_cast<const GpuHtSample*>(htSampleLog.mapped());
  for (uint32_t y = 0; y < push.tileHeight; ++y)
    for (uint32_t x = 0; x < push.tileWidth; ++x) {
      const size_t i = size_t(y) * push.tileWidth + x;
      const uint32_t n = std::min<uint32_t>(px[i].directions, HT_SAMPLE_LOG_SLOTS);
      auto& samples = out.htSamples[size_t(push.tileY + y) * s.width + push.tileX + x];
      for (uint32_t k = 0; k < n; ++k) {
        const GpuHtSample& g = log[i * HT_SAMPLE_LOG_SLOTS + k];
        samples.push_back({g.dir, g.h, uint64_t(g.candidate.x) | uint64_t(g.candidate.y) << 32, int(g.level),
                           g.weight});
      }
    }
}

GpuRenderResult GpuRenderer::render(const RenderSettings& s) {
  impl_->checkMethod(s);
  return render(s, prepareTables(*impl_->hostScene, s.method, s.options, TablesFor::Gpu));
}

void GpuRenderer::uploadTables(const RenderSettings& s, const MethodTables& tables) {
  impl_->checkMethod(s);
  impl_->usePipeline(s.method, usesBrdfTable(s));
  impl_->uploadTables(s, tables);
}

GpuRenderResult GpuRenderer::render(const RenderSettings& s, const MethodTables& tables) {
  Impl& m = *impl_;
  m.checkMethod(s);
  m.usePipeline(s.method, usesBrdfTable(s));
  m.uploadTables(s, tables);
  const auto [tileW, tileH] = m.prepareTiles(s);
  m.warmPipeline(s);
  const auto start = std::chrono::steady_clock::now();

  GpuRenderResult out;
  out.gpuSeconds = m.queries ? 0.0 : -1.0;
  out.readbackSeconds = m.queries ? 0.0 : -1.0;
  RenderResult& r = out.result;
  r.image.width = s.width;
  r.image.height = s.height;
  r.image.pixels.assign(size_t(s.width) * s.height, glm::vec3(0.0f));
  if (s.pixelCounts) r.pixelDirections.assign(size_t(s.width) * s.height, 0);
  const uint32_t tileCount = ((uint32_t(s.width) + tileW - 1) / tileW) * ((uint32_t(s.height) + tileH - 1) / tileH);
  out.tileWidth = int(tileW);
  out.tileHeight = int(tileH);
  int lastReported = -1;
  uint32_t limit = m.batchLimit > 0 ? m.batchLimit : firstBatchLimit(s, m.envOrder, m.occluders);
  for (uint32_t y = 0; y < uint32_t(s.height); y += tileH)
    for (uint32_t x = 0; x < uint32_t(s.width); x += tileW) {
      GpuPush push = tilePush(s, x, y, tileW, tileH);
      m.bindScratch(s, push);
      m.renderTile(s, push, limit, out);
      m.readTile(s, push, out);
      ++out.tiles;
      if (s.progress) {
        const int percent = int(100.0 * out.tiles / tileCount);
        if (percent / 10 > lastReported / 10 || out.tiles == int(tileCount)) {
          lastReported = percent;
          std::fprintf(stderr, "\rrender: %3d%%%s", percent, out.tiles == int(tileCount) ? "\n" : "");
          std::fflush(stderr);
        }
      }
    }
  out.batchLimit = limit;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace ht
