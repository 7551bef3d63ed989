// The GPU renderer: device, pipelines, the scene's upload, tiles, batches,
// timestamps and read-back; each method's part through its spec's
// GpuSupport (method.h) and its GpuMethodState (gpu_method.h).
#include "gpu_render.h"
#include "gpu_render_impl.h"

#include <unistd.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>

#include <fmt/format.h>
#include <glm/geometric.hpp>

#include "common.h"  // shaders/common.h
#include "error.h"
#include "healpix.h"
#include "ht.h"
#include "sampling.h"
#include "vk/buffers.h"
#include "vk/device.h"
#include "vk/pipeline.h"

namespace ht {
namespace {

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
    {HT_BINDING_BVH_NODES, 0, sizeof(GpuBvhNode)},
    {HT_BINDING_BVH_ORDER, 0, sizeof(uint32_t)},
    {HT_BINDING_CUT_TREE_TEXELS, 0, 0, vk::BindingKind::UniformTexel},
    {HT_BINDING_CUT_RECORD_TEXELS, 0, 0, vk::BindingKind::UniformTexel},
    {HT_BINDING_CUT_LOOKUP_TEXELS, 0, 0, vk::BindingKind::UniformTexel},
    {HT_BINDING_SPHERE_TEXELS, 0, 0, vk::BindingKind::UniformTexel},
    {HT_BINDING_BVH_NODE_TEXELS, 0, 0, vk::BindingKind::UniformTexel},
    {HT_BINDING_BVH_ORDER_TEXELS, 0, 0, vk::BindingKind::UniformTexel},
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

// Batches a submission holds, at most.
constexpr uint64_t kBatchesPerSubmission = 64;

static_assert(uint32_t(SamplerKind::Independent) == HT_SAMPLER_INDEPENDENT &&
              uint32_t(SamplerKind::Stratified) == HT_SAMPLER_STRATIFIED);
static_assert(kBvhLeafSize == HT_BVH_LEAF_SIZE);
static_assert(int(MaterialType::Lambert) == HT_MATERIAL_LAMBERT && int(MaterialType::Phong) == HT_MATERIAL_PHONG &&
              int(MaterialType::Ggx) == HT_MATERIAL_GGX);

// Loop iterations one pixel may spend in one dispatch, a quarter of what
// llvmpipe allows an invocation in all (GpuPixelState).
constexpr uint64_t kLoopIterationsPerBatch = 16384;

// Samples (ht*: traversal steps) per pixel and dispatch, from the spec's
// rough count of the loop iterations each costs. Only the first guess: a
// dispatch whose loops were cut short makes the renderer halve it and start
// the tile again.
uint32_t firstBatchLimit(const RenderSettings& s, int envOrder, size_t shapes) {
  const GpuSupport& g = *methodSpec(s.method).gpu;
  const uint64_t cost = g.loopCost ? g.loopCost(s, envOrder, shapes) : gpuDescentCost(envOrder, shapes);
  return uint32_t(std::clamp<uint64_t>(kLoopIterationsPerBatch / std::max<uint64_t>(cost, 1), 1, 1u << 20));
}

// Directions a pixel draws, roughly.
uint64_t directionsPerPixel(const RenderSettings& s) {
  const GpuSupport& g = *methodSpec(s.method).gpu;
  return g.directionsPerPixel ? g.directionsPerPixel(s) : uint64_t(std::max(s.spp, 1));
}

bool usesBrdfTable(const RenderSettings& s) {
  const GpuSupport& g = *methodSpec(s.method).gpu;
  return g.brdfTable && g.brdfTable(s);
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

std::string shaderDirNextToExecutable() {
  std::error_code ec;
  std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return "shaders";
  return (exe.parent_path() / "shaders").string();
}

GpuRenderer::Impl::Impl(const GpuOptions& o)
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

GpuRenderer::Impl::~Impl() {
  if (ctx.device) ctx.fn.vkDeviceWaitIdle(ctx.device);
  if (queries) ctx.fn.vkDestroyQueryPool(ctx.device, queries, nullptr);
}

void GpuRenderer::Impl::usePipeline(Method method, bool brdfTable) {
  const uint32_t capSlots = uint32_t(std::min<size_t>(occluders, HT_MAX_CAPS));
  if (pipelineMethod == uint32_t(method) && pipelineTexels == texels && pipelineCapSlots == capSlots &&
      pipelineBrdfTable == brdfTable)
    return;
  const uint32_t specialization[] = {uint32_t(method), texels ? 1u : 0u, capSlots, brdfTable ? 1u : 0u};
  shaderName =
      fmt::format("{}.{}.spv", methodSpec(method).gpu->shader, usesFloat64(method) ? "fp64" : "fp32");
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

void GpuRenderer::Impl::bindScene() {
  pipeline->setBuffer(HT_BINDING_SCENE, sceneBuffer);
  pipeline->setBuffer(HT_BINDING_MATERIALS, materials);
  pipeline->setBuffer(HT_BINDING_SPHERES, spheres);
  pipeline->setBuffer(HT_BINDING_PLANES, planes);
  pipeline->setBuffer(HT_BINDING_BVH_NODES, bvhNodes);
  pipeline->setBuffer(HT_BINDING_BVH_ORDER, bvhOrder);
  for (auto& [binding, t] : texelBuffers) {
    vk::Buffer* buffer = texels ? t.buffer : nullptr;
    if (!buffer) {
      buffer = &placeholders[t.format];
      if (!buffer->handle()) *buffer = vk::Buffer(ctx, 16, vk::MemoryUse::DeviceLocal);  // one texel of the widest format
    }
    pipeline->setTexelBuffer(binding, buffer->texelView(t.format));
  }
}

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
             nodes <= (uint64_t(1) << HT_HT_VEC2_CHUNK_SHIFT) && 3 * nodes <= maxTexels &&
             scene.spheres.size() <= maxTexels && 2 * scene.sphereBvh.nodes.size() <= maxTexels;
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
  // The spheres' BVH where the scene has one (readSceneFile builds it): each
  // node with the node after its subtree, found from the last node back.
  const Bvh& bvh = scene.sphereBvh;
  std::vector<GpuBvhNode> bvhNodes(bvh.spheres == scene.spheres.size() ? bvh.nodes.size() : 0);
  for (size_t i = bvhNodes.size(); i-- > 0;) {
    const BvhNode& n = bvh.nodes[i];
    if (n.count > HT_BVH_LEAF_SIZE || n.first >= (1u << 29)) throw Error("internal: a BVH leaf beyond the GPU's node format");
    bvhNodes[i] = {n.lo, n.count > 0 ? uint32_t(i + 1) : bvhNodes[n.first].skip, n.hi,
                   n.count > 0 ? n.first << 3 | n.count : 0u};
  }
  gs.bvhNodeCount = uint32_t(bvhNodes.size());

  m.sceneBuffer = vk::Buffer(ctx, sizeof(GpuScene), vk::MemoryUse::DeviceLocal);
  m.sceneBuffer.upload(&gs, sizeof(gs));
  m.materials = uploadArray(ctx, materials);
  m.spheres = uploadArray(ctx, spheres);
  m.planes = uploadArray(ctx, planes);
  m.bvhNodes = uploadArray(ctx, bvhNodes);
  m.bvhOrder = uploadArray(ctx, bvhNodes.empty() ? std::vector<uint32_t>{} : bvh.order);
  std::vector<glm::vec4> shapes;
  for (const Sphere& s : scene.spheres) shapes.emplace_back(s.center, s.radius);
  m.sphereShapes = uploadArray(ctx, shapes);
  m.texelBuffers[HT_BINDING_SPHERE_TEXELS].buffer = shapes.empty() ? nullptr : &m.sphereShapes;
  m.texelBuffers[HT_BINDING_BVH_NODE_TEXELS].buffer = bvhNodes.empty() ? nullptr : &m.bvhNodes;
  m.texelBuffers[HT_BINDING_BVH_ORDER_TEXELS].buffer = bvhNodes.empty() ? nullptr : &m.bvhOrder;
  m.bindScene();
  m.scene = gs;
  m.sceneFields = gs;
  m.sceneTexels = m.texelBuffers;
  m.envOrder = env.order;
  m.materialCount = scene.materials.size();
  m.occluders = scene.spheres.size() + scene.planes.size();
  // What a ray costs, in spheres and planes tested: through the BVH, about
  // a few leaves' worth per level.
  const size_t n = scene.spheres.size();
  m.rayCost = scene.planes.size() + (bvhNodes.empty() ? n : std::min<size_t>(n, 8 + 4 * size_t(std::bit_width(n))));
  m.states.clear();
  m.hostScene = &scene;
  m.hasScene = true;
}

void GpuRenderer::Impl::checkMethod(const RenderSettings& s) const {
  if (!hasScene) throw Error("internal: GpuRenderer::render before setScene");
  if (!gpuSupportsMethod(s.method))
    throw Error(fmt::format("method {} has no GPU version (it runs on the CPU reference only); use --device cpu",
                            methodName(s.method)));
  if (precision == GpuPrecision::Fp64 && !ctx.float64)
    throw Error(fmt::format("--gpu-precision fp64 needs shaderFloat64, which {} lacks", info.name));
  if (methodSpec(s.method).gpu->float64 && !usesFloat64(s.method))
    throw Error(fmt::format("method {} needs shaderFloat64 on the GPU ({} has none, or --gpu-precision is fp32); "
                            "use --device cpu", methodName(s.method), info.name));
  if (methodSpec(s.method).gpu->subgroupVote && !ctx.info.subgroupVote)
    throw Error(fmt::format("method {} needs subgroup vote operations in compute shaders on the GPU, which {} lacks; "
                            "use --device cpu", methodName(s.method), info.name));
}

// Square tiles, a multiple of the workgroup, sized so that one dispatch
// draws at most directionsPerDispatch directions (and its scratch takes at
// most scratchBudget); their buffers.
std::pair<uint32_t, uint32_t> GpuRenderer::Impl::prepareTiles(const RenderSettings& s) {
  uint32_t side = std::min(maxTileSide, methodSpec(s.method).gpu->maxTileSide);
  GpuMethodState* state = methodState(s.method);
  const uint64_t scratch = state ? state->scratchBytesPerPixel(s) : 0;
  if (methodSpec(s.method).gpu->wholeImage) {
    side = (uint32_t(std::max(s.width, s.height)) + kWorkgroupSize - 1) / kWorkgroupSize * kWorkgroupSize;
  } else {
    while (side > kWorkgroupSize && uint64_t(side) * side * directionsPerPixel(s) > directionsPerDispatch(ctx.info))
      side = std::max(kWorkgroupSize, side / 2 / kWorkgroupSize * kWorkgroupSize);
    while (scratch > 0 && side > kWorkgroupSize && uint64_t(side) * side * scratch > scratchBudget(ctx.info))
      side = std::max(kWorkgroupSize, side / 2 / kWorkgroupSize * kWorkgroupSize);
  }
  const uint32_t tileW = std::min<uint32_t>(side, uint32_t(s.width));
  const uint32_t tileH = std::min<uint32_t>(side, uint32_t(s.height));
  const VkDeviceSize tilePixels = VkDeviceSize(tileW) * tileH;
  // lavapipe's device memory is the process's, its pages made at their first
  // write: a new buffer is filled here, before the render's clock starts, as
  // a GPU's memory is in place once allocated.
  std::vector<vk::Buffer*> fresh;
  const std::function<bool(vk::Buffer&, VkDeviceSize)> deviceBuffer = [&](vk::Buffer& b, VkDeviceSize bytes) {
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
  if (state) {
    GpuTileContext tile{ctx, tileW, tileH, deviceBuffer, recordHtSamples};
    state->prepareScratch(tile, s);
  }
  if (!fresh.empty())
    ctx.submitAndWait([&](VkCommandBuffer cmd) {
      for (vk::Buffer* b : fresh) ctx.fn.vkCmdFillBuffer(cmd, b->handle(), 0, VK_WHOLE_SIZE, 0);
    });
  return {tileW, tileH};
}

// lavapipe makes a pipeline's machine code (or loads it from its disk
// cache: some 30 ms for ht) at the pipeline's first dispatch, not when it
// is created. A dispatch of no pixels, once the buffers are bound, does it
// before the render, as drivers that compile in vkCreateComputePipelines do.
void GpuRenderer::Impl::warmPipeline(const RenderSettings& s) {
  if (pipelineRan) return;
  GpuPush push = tilePush(s, 0, 0, 0, 0);
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
  const GpuSupport& g = *methodSpec(s.method).gpu;
  for (uint32_t batch = 0;;) {
    // The sampling methods need ceil(spp / limit) batches; HT's traversal
    // takes some steps per sample (GpuSupport::stepsPerSample), read back
    // to see when it is done.
    const uint64_t expected = (g.stepsPerSample * spp + g.fixedSteps + limit - 1) / limit;
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

// The finished tile's pixels and counters, and what its method reads back.
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
  if (GpuMethodState* state = methodState(s.method)) state->readTile(s, push, px, out);
}

bool gpuSupportsMethod(Method m) { return methodSpec(m).gpu != nullptr; }

std::string gpuSceneLimit(Method method, const Scene& scene) {
  const GpuSupport* g = methodSpec(method).gpu;
  return g && g->sceneLimit ? g->sceneLimit(method, scene) : std::string();
}

GpuMethodState* GpuRenderer::Impl::methodState(Method method) {
  const GpuSupport& g = *methodSpec(method).gpu;
  if (!g.makeState) return nullptr;
  std::unique_ptr<GpuMethodState>& state = states[g.makeState];
  if (!state) state = g.makeState();
  return state.get();
}

// The scene's fields and views as setScene left them, with the method's
// part filled in: uploaded and bound where they changed (its tables
// uploaded at their first render, and again when they are other tables).
void GpuRenderer::Impl::uploadTables(const RenderSettings& s, const MethodTables& t) {
  if (const std::string limit = gpuSceneLimit(s.method, *hostScene); !limit.empty()) throw Error(limit);
  GpuScene next = sceneFields;
  texelBuffers = sceneTexels;
  if (GpuMethodState* state = methodState(s.method)) {
    GpuUploadContext c{ctx, *hostScene, next, texelBuffers, usesFloat64(s.method), envOrder, materialCount};
    state->upload(c, s, t);
  }
  if (std::memcmp(&next, &scene, sizeof(GpuScene)) != 0) {
    scene = next;
    sceneBuffer.upload(&scene, sizeof(scene));
  }
  // Always: a method's new buffer may take a freed one's place in memory,
  // so that neither its address nor its object tells that its view is new.
  bindScene();
}

GpuPush GpuRenderer::Impl::tilePush(const RenderSettings& s, uint32_t x, uint32_t y, uint32_t tileW, uint32_t tileH) {
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
  push.samplerKind = uint32_t(s.options.sampler);
  push.canaryLoops = 2;
  push.canaryZero = 0;
  push.pixelState = pixelState.address();
  const GpuSupport& g = *methodSpec(s.method).gpu;
  if (g.push) g.push(s, push);
  if (GpuMethodState* state = methodState(s.method)) state->bindScratch(s, push);
  return push;
}

GpuRenderResult GpuRenderer::render(const RenderSettings& s) {
  impl_->checkMethod(s);
  return render(s, prepareTables(*impl_->hostScene, s.method, optionsForSpp(s.options, s.spp), TablesFor::Gpu));
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
  uint32_t limit = m.batchLimit > 0 ? m.batchLimit : firstBatchLimit(s, m.envOrder, m.rayCost);
  for (uint32_t y = 0; y < uint32_t(s.height); y += tileH)
    for (uint32_t x = 0; x < uint32_t(s.width); x += tileW) {
      GpuPush push = m.tilePush(s, x, y, tileW, tileH);
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
