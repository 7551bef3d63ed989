#include "gpu_render.h"

#include <unistd.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>

#include <fmt/format.h>
#include <glm/geometric.hpp>

#include "common.h"  // shaders/common.h
#include "healpix.h"
#include "sampling.h"
#include "vk/buffers.h"
#include "vk/device.h"
#include "vk/pipeline.h"

namespace ht {
namespace {

using namespace ht::gpu;

// Directions per dispatch: bounds the time of one dispatch (about 1 s on
// lavapipe with 2 cores for mis, far less on a GPU).
constexpr uint64_t kDirectionsPerDispatch = uint64_t(1) << 22;

static_assert(int(Method::Uniform) == HT_METHOD_UNIFORM && int(Method::Cosine) == HT_METHOD_COSINE &&
              int(Method::Env) == HT_METHOD_ENV && int(Method::Brdf) == HT_METHOD_BRDF &&
              int(Method::Mis) == HT_METHOD_MIS && int(Method::Ht) == HT_METHOD_HT &&
              int(Method::HtVis) == HT_METHOD_HT_VIS && int(Method::HtBiased) == HT_METHOD_HT_BIASED &&
              int(Method::HtVisBiased) == HT_METHOD_HT_VIS_BIASED);
static_assert(int(MaterialType::Lambert) == HT_MATERIAL_LAMBERT && int(MaterialType::Phong) == HT_MATERIAL_PHONG &&
              int(MaterialType::Ggx) == HT_MATERIAL_GGX);

constexpr vk::BindingLayout kBindings[] = {
    {HT_BINDING_SCENE, sizeof(GpuScene), 0},
    {HT_BINDING_MATERIALS, 0, sizeof(GpuMaterial)},
    {HT_BINDING_SPHERES, 0, sizeof(GpuSphere)},
    {HT_BINDING_PLANES, 0, sizeof(GpuPlane)},
    {HT_BINDING_PIXELS, 0, sizeof(GpuPixel)},
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

bool gpuSupportsMethod(Method m) {
  return m == Method::Uniform || m == Method::Cosine || m == Method::Env || m == Method::Brdf || m == Method::Mis;
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
  std::string shaderName;
  std::optional<vk::ComputePipeline> pipeline;
  VkQueryPool queries = VK_NULL_HANDLE;
  uint64_t timestampMask = 0;
  uint32_t maxTileSide = 512;

  // Per scene.
  bool hasScene = false;
  std::vector<vk::Buffer> chunks;
  vk::Buffer sceneBuffer, materials, spheres, planes;
  // Per tile.
  vk::Buffer pixels;

  explicit Impl(const GpuOptions& o)
      : ctx(vk::ContextOptions{o.deviceIndex, o.validation, !o.forceFp32, o.validationLog}) {
    info = toInfo(ctx.info);
    maxTileSide = std::max<uint32_t>(kWorkgroupSize, uint32_t(std::max(o.maxTileSide, 1)) / kWorkgroupSize * kWorkgroupSize);
    shaderName = ctx.float64 ? "render.fp64.spv" : "render.fp32.spv";
    const std::string dir = o.shaderDir.empty() ? shaderDirNextToExecutable() : o.shaderDir;
    pipeline.emplace(ctx, (std::filesystem::path(dir) / shaderName).string(), kBindings, uint32_t(sizeof(GpuPush)),
                     std::array<uint32_t, 3>{kWorkgroupSize, kWorkgroupSize, 1});
    if (ctx.info.timestampValidBits > 0) {
      VkQueryPoolCreateInfo q{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
      q.queryType = VK_QUERY_TYPE_TIMESTAMP;
      q.queryCount = 2;
      vk::check(vkCreateQueryPool(ctx.device, &q, nullptr, &queries), "vkCreateQueryPool");
      timestampMask = ctx.info.timestampValidBits >= 64 ? ~uint64_t(0)
                                                        : (uint64_t(1) << ctx.info.timestampValidBits) - 1;
    }
  }
  ~Impl() {
    if (ctx.device) vkDeviceWaitIdle(ctx.device);
    if (queries) vkDestroyQueryPool(ctx.device, queries, nullptr);
  }
};

GpuRenderer::GpuRenderer(const GpuOptions& options) : impl_(std::make_unique<Impl>(options)) {}
GpuRenderer::~GpuRenderer() = default;

const GpuDeviceInfo& GpuRenderer::device() const { return impl_->info; }
bool GpuRenderer::float64() const { return impl_->ctx.float64; }
std::string GpuRenderer::shaderName() const { return impl_->shaderName; }
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
  uploadChunked(ctx, env.radiance.data(), pixelCount, sizeof(glm::vec3), kRadianceChunkElements, m.chunks,
                gs.radiance, "environment radiance");
  uploadChunked(ctx, env.tree.avgv.data(), env.tree.avgv.size(), sizeof(float), kTreeChunkElements, m.chunks,
                gs.treeAvg, "environment average tree");
  uploadChunked(ctx, env.tree.maxv.data(), env.tree.maxv.size(), sizeof(float), kTreeChunkElements, m.chunks,
                gs.treeMax, "environment max tree");

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
  m.pipeline->setBuffer(HT_BINDING_SCENE, m.sceneBuffer);
  m.pipeline->setBuffer(HT_BINDING_MATERIALS, m.materials);
  m.pipeline->setBuffer(HT_BINDING_SPHERES, m.spheres);
  m.pipeline->setBuffer(HT_BINDING_PLANES, m.planes);
  m.hasScene = true;
}

GpuRenderResult GpuRenderer::render(const RenderSettings& s) {
  Impl& m = *impl_;
  if (!m.hasScene) throw Error("internal: GpuRenderer::render before setScene");
  if (!gpuSupportsMethod(s.method))
    throw Error(fmt::format("method {} is not implemented on the GPU yet (uniform, cosine, env, brdf, mis are); "
                            "use --device cpu", methodName(s.method)));
  const auto start = std::chrono::steady_clock::now();

  // Square tiles, a multiple of the workgroup, sized so that one dispatch
  // draws at most kDirectionsPerDispatch directions.
  const uint64_t perPixel = uint64_t(std::max(s.spp, 1)) * (s.method == Method::Mis ? 2 : 1);
  uint32_t side = m.maxTileSide;
  while (side > kWorkgroupSize && uint64_t(side) * side * perPixel > kDirectionsPerDispatch)
    side = std::max(kWorkgroupSize, side / 2 / kWorkgroupSize * kWorkgroupSize);
  const uint32_t tileW = std::min<uint32_t>(side, uint32_t(s.width));
  const uint32_t tileH = std::min<uint32_t>(side, uint32_t(s.height));
  const VkDeviceSize pixelBytes = VkDeviceSize(tileW) * tileH * sizeof(GpuPixel);
  if (m.pixels.size() < pixelBytes) {
    m.pixels = vk::Buffer(m.ctx, pixelBytes, vk::MemoryUse::Readback);
    m.pipeline->setBuffer(HT_BINDING_PIXELS, m.pixels);
  }

  GpuRenderResult out;
  RenderResult& r = out.result;
  r.image.width = s.width;
  r.image.height = s.height;
  r.image.pixels.assign(size_t(s.width) * s.height, glm::vec3(0.0f));
  const uint32_t tilesX = (uint32_t(s.width) + tileW - 1) / tileW;
  const uint32_t tilesY = (uint32_t(s.height) + tileH - 1) / tileH;
  const uint32_t tileCount = tilesX * tilesY;
  double gpuNs = 0.0;
  int lastReported = -1;

  for (uint32_t ty = 0; ty < tilesY; ++ty)
    for (uint32_t tx = 0; tx < tilesX; ++tx) {
      GpuPush push{};
      push.width = uint32_t(s.width);
      push.height = uint32_t(s.height);
      push.tileX = tx * tileW;
      push.tileY = ty * tileH;
      push.tileWidth = std::min(tileW, uint32_t(s.width) - push.tileX);
      push.tileHeight = std::min(tileH, uint32_t(s.height) - push.tileY);
      push.method = uint32_t(s.method);
      push.spp = uint32_t(std::max(s.spp, 1));
      push.seed = s.seed;
      m.ctx.submitAndWait([&](VkCommandBuffer cmd) {
        // Uploads (host writes, staging copies) before the shader reads.
        VkMemoryBarrier before{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
        before.srcAccessMask = VK_ACCESS_HOST_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
        before.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT;
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_HOST_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                             VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &before, 0, nullptr, 0, nullptr);
        if (m.queries) {
          vkCmdResetQueryPool(cmd, m.queries, 0, 2);
          vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, m.queries, 0);
        }
        m.pipeline->dispatch(cmd, &push, (push.tileWidth + kWorkgroupSize - 1) / kWorkgroupSize,
                             (push.tileHeight + kWorkgroupSize - 1) / kWorkgroupSize);
        if (m.queries) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, m.queries, 1);
        VkMemoryBarrier after{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
        after.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
        after.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &after, 0,
                             nullptr, 0, nullptr);
      });
      if (m.queries) {
        uint64_t stamps[2];
        vk::check(vkGetQueryPoolResults(m.ctx.device, m.queries, 0, 2, sizeof(stamps), stamps, sizeof(uint64_t),
                                        VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
                  "vkGetQueryPoolResults");
        gpuNs += double((stamps[1] - stamps[0]) & m.timestampMask) * double(m.ctx.info.timestampPeriodNs);
      }
      m.pixels.invalidate();
      const auto* px = static_cast<const GpuPixel*>(m.pixels.mapped());
      for (uint32_t y = 0; y < push.tileHeight; ++y)
        for (uint32_t x = 0; x < push.tileWidth; ++x) {
          const GpuPixel& p = px[size_t(y) * push.tileWidth + x];
          r.image.at(int(push.tileX + x), int(push.tileY + y)) = p.radiance;
          r.shadedPixels += p.shaded;
          r.counters.directions += p.directions;
          r.counters.shadowRays += p.shadowRays;
          r.counters.htNodes += p.htNodes;
        }
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
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  out.gpuSeconds = m.queries ? gpuNs * 1e-9 : -1.0;
  return out;
}

}  // namespace ht
