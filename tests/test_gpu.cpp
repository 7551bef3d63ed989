// The Vulkan compute path against the CPU reference, on whatever Vulkan
// device the machine has (lavapipe in CI), with the Khronos validation layer
// on: every message of severity warning or error fails the run.
//
// - the shaders' float arithmetic is all `precise` (NoContraction), and the
//   SPIR-V interface matches shaders/common.h;
// - HEALPix in the shaders against host/healpix.cpp, direction -> pixel and
//   pixel -> direction, fp64 and fp32 variants;
// - per baseline method: the GPU image against the CPU image of the same
//   seed (identical within a tolerance for nearly every pixel; the fraction
//   that differs is printed), and a per-pixel test at 64 spp against CPU
//   renders with other seeds, with the image means' relative difference;
// - tiles and odd image sizes, an all-black environment, refused methods.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <cstdlib>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "common.h"
#include "error.h"
#include "gpu_render.h"
#include "healpix.h"
#include "ht.h"
#include "render.h"
#include "sampling.h"
#include "scene.h"
#include "vk/buffers.h"
#include "vk/device.h"
#include "vk/pipeline.h"

namespace ht {
namespace {

const std::string kShaderDir = HT_SHADER_DIR;
const std::string kData = HT_TEST_DATA;

// Every renderer and context of this process reports here; checked after
// each test and once more when the process ends (messages at destruction).
std::shared_ptr<vk::ValidationLog> validationLog() {
  static auto log = std::make_shared<vk::ValidationLog>();
  return log;
}

void expectNoValidationMessages() {
  const vk::ValidationLog& log = *validationLog();
  EXPECT_EQ(log.errors, 0u) << (log.messages.empty() ? "" : log.messages.front());
  EXPECT_EQ(log.warnings, 0u) << (log.messages.empty() ? "" : log.messages.front());
}

class ValidationCheck : public ::testing::Environment {
 public:
  void TearDown() override { expectNoValidationMessages(); }
};
const auto* const kValidationCheck = ::testing::AddGlobalTestEnvironment(new ValidationCheck);

GpuOptions gpuOptions(bool fp32 = false) {
  GpuOptions o;
  o.validation = true;
  o.validationLog = validationLog();
  o.shaderDir = kShaderDir;
  o.precision = fp32 ? GpuPrecision::Fp32 : GpuPrecision::Fp64;
  return o;
}

// spheres.json (Lambert, Phong and GGX spheres on a plane) under sunrise at
// Nside 32 and a yaw, so that the environment stays small and the yaw path runs.
const Scene& testScene() {
  static const Scene scene = [] {
    Scene s = readSceneFile(kData + "/scenes/spheres.json");
    s.environmentDesc.nside = 32;
    s.environmentDesc.yaw = 25.0f;
    loadEnvironment(s);
    return s;
  }();
  return scene;
}

// ris: candidates per sample, few so that the CPU references stay quick.
constexpr int kTestRisCandidates = 4;
// wis: one order below the test scenes' maps, so that wis-biased averages pixels.
constexpr int kTestWisOrder = 4;

RenderSettings settings(Method method, int spp, uint32_t seed, int width = 80, int height = 40) {
  RenderSettings s;
  s.method = method;
  s.spp = spp;
  s.seed = seed;
  s.width = width;
  s.height = height;
  s.options.risCandidates = kTestRisCandidates;
  s.options.wisOrder = kTestWisOrder;
  return s;
}

// ---------------------------------------------------------------- SPIR-V

std::vector<std::string> spirvFiles() {
  std::vector<std::string> files;
  for (const char* name : {"baselines", "ht", "competitors", "frontier", "restir", "healpix_test"})
    for (const char* variant : {"fp64", "fp32"}) files.push_back(kShaderDir + "/" + name + "." + variant + ".spv");
  return files;
}

TEST(GpuShaders, EveryFloatOperationIsPrecise) {
  // OpFAdd, OpFSub, OpFMul, OpFDiv, OpFRem, OpFMod, OpVectorTimesScalar, OpDot:
  // each must carry NoContraction, or the driver may fuse or reorder it and
  // the GPU stops reproducing the CPU's rounding.
  const std::vector<uint32_t> arithmetic = {129, 131, 133, 136, 140, 141, 142, 148};
  for (const std::string& path : spirvFiles()) {
    std::vector<uint32_t> code = vk::loadSpirv(path);
    std::vector<uint32_t> results, decorated;
    for (size_t i = 5; i < code.size(); i += code[i] >> 16) {
      const uint32_t op = code[i] & 0xFFFF;
      if (op == 71 && code[i + 2] == 42) decorated.push_back(code[i + 1]);  // OpDecorate NoContraction
      if (std::find(arithmetic.begin(), arithmetic.end(), op) != arithmetic.end()) results.push_back(code[i + 2]);
    }
    std::sort(decorated.begin(), decorated.end());
    size_t missing = 0;
    for (uint32_t id : results)
      if (!std::binary_search(decorated.begin(), decorated.end(), id)) ++missing;
    EXPECT_GT(results.size(), 20u) << path;
    EXPECT_EQ(missing, 0u) << path << ": " << missing << " of " << results.size()
                           << " float operations lack `precise` (NoContraction)";
  }
}

TEST(GpuShaders, InterfaceMatchesCommonHeader) {
  for (const std::string& path : spirvFiles()) {
    if (path.find("healpix_test") != std::string::npos) continue;
    SCOPED_TRACE(path);
    vk::SpirvInterface s = vk::reflectSpirv(vk::loadSpirv(path));
    EXPECT_EQ(s.pushConstantSize, sizeof(gpu::GpuPush));
    EXPECT_EQ(s.localSize, (std::array<uint32_t, 3>{HT_WORKGROUP_SIZE, HT_WORKGROUP_SIZE, 1}));
    for (const vk::SpirvInterface::Binding& b : s.bindings) {
      EXPECT_EQ(b.set, 0u);
      switch (b.binding) {
        case HT_BINDING_SCENE:
          EXPECT_EQ(b.staticSize, sizeof(gpu::GpuScene));
          EXPECT_EQ(b.kind, vk::BindingKind::Uniform);
          break;
        case HT_BINDING_MATERIALS: EXPECT_EQ(b.runtimeStride, sizeof(gpu::GpuMaterial)); break;
        case HT_BINDING_SPHERES: EXPECT_EQ(b.runtimeStride, sizeof(gpu::GpuSphere)); break;
        case HT_BINDING_PLANES: EXPECT_EQ(b.runtimeStride, sizeof(gpu::GpuPlane)); break;
        case HT_BINDING_PIXELS: EXPECT_EQ(b.runtimeStride, sizeof(gpu::GpuPixel)); break;
        case HT_BINDING_BVH_NODES: EXPECT_EQ(b.runtimeStride, sizeof(gpu::GpuBvhNode)); break;
        case HT_BINDING_BVH_ORDER: EXPECT_EQ(b.runtimeStride, sizeof(uint32_t)); break;
        case HT_BINDING_RADIANCE_TEXELS:
        case HT_BINDING_TREE_AVG_TEXELS:
        case HT_BINDING_TREE_MAX_TEXELS:
        case HT_BINDING_HT_CENTERS_TEXELS:
        case HT_BINDING_HT_CONES_TEXELS:
        case HT_BINDING_FRONTIER_CHROMA_TEXELS:
        case HT_BINDING_FRONTIER_CENTROID_TEXELS:
        case HT_BINDING_FRONTIER_BINS_TEXELS:
        case HT_BINDING_CUT_TREE_TEXELS:
        case HT_BINDING_CUT_RECORD_TEXELS:
        case HT_BINDING_CUT_LOOKUP_TEXELS:
        case HT_BINDING_SPHERE_TEXELS:
        case HT_BINDING_BVH_NODE_TEXELS:
        case HT_BINDING_BVH_ORDER_TEXELS: EXPECT_EQ(b.kind, vk::BindingKind::UniformTexel); break;
        default: ADD_FAILURE() << "unexpected binding " << b.binding;
      }
    }
    EXPECT_EQ(s.bindings.size(), size_t(HT_BINDING_COUNT));
  }
}

TEST(GpuShaders, MissingSpirvIsAOneLineError) {
  GpuOptions o = gpuOptions();
  o.shaderDir = "/nonexistent/shaders";
  try {
    GpuRenderer r(o);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("SPIR-V shader not found"), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
  }
}

// ---------------------------------------------------------------- devices

TEST(GpuDevice, ListsAUsableDevice) {
  std::vector<GpuDeviceInfo> devices = listGpuDevices();
  ASSERT_FALSE(devices.empty());
  const int best = defaultGpuDevice(devices);
  ASSERT_GE(best, 0) << devices[0].name << ": " << devices[0].unusableReason;
  for (const GpuDeviceInfo& d : devices)
    std::printf("[ device   ] [%u] %s: %s, %s, Vulkan %s, fp64 %d, timestamps %d%s\n", d.index, d.name.c_str(),
                d.type.c_str(), d.driver.c_str(), d.apiVersion.c_str(), d.shaderFloat64, d.timestamps,
                int(d.index) == best ? " (default)" : "");
  GpuOptions o = gpuOptions();
  o.deviceIndex = int(devices.size());
  EXPECT_THROW(GpuRenderer r(o), Error);
}

TEST(GpuDevice, ValidationMessagesAreCounted) {
  // The counter the other tests rely on sees an invalid call (a zero-sized buffer).
  auto log = std::make_shared<vk::ValidationLog>();
  log->print = false;
  {
    vk::ContextOptions co;
    co.validation = true;
    co.validationLog = log;
    vk::Context ctx(co);
    VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    info.size = 0;
    info.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    VkBuffer buffer = VK_NULL_HANDLE;
    if (ctx.fn.vkCreateBuffer(ctx.device, &info, nullptr, &buffer) == VK_SUCCESS && buffer) ctx.fn.vkDestroyBuffer(ctx.device, buffer, nullptr);
  }
  EXPECT_GE(log->errors, 1u);
}

// ---------------------------------------------------------------- HEALPix

struct HealpixItem {
  glm::vec3 dir;
  uint32_t pixel;
  float dx, dy;
};
static_assert(sizeof(HealpixItem) == 24);

class GpuHealpix : public ::testing::TestWithParam<bool> {};  // fp32?

TEST_P(GpuHealpix, MatchesCpu) {
  const bool fp32 = GetParam();
  vk::ContextOptions co;
  co.validation = true;
  co.validationLog = validationLog();
  co.useFloat64 = !fp32;
  vk::Context ctx(co);
  if (!fp32 && !ctx.float64) GTEST_SKIP() << "device without shaderFloat64";
  const vk::BindingLayout bindings[] = {{0, 0, sizeof(HealpixItem)}, {1, 0, 4}, {2, 0, 12}};
  vk::ComputePipeline pipeline(ctx, kShaderDir + (fp32 ? "/healpix_test.fp32.spv" : "/healpix_test.fp64.spv"), bindings,
                               8, {64, 1, 1});
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  for (int order : {0, 3, 5, 8, 11, 13}) {
    // Half random directions, half points on pixel borders (dx or dy = 0).
    const uint32_t n = 1 << 16;
    std::vector<HealpixItem> items(n);
    for (uint32_t i = 0; i < n; ++i) {
      HealpixItem& it = items[i];
      it.pixel = uint32_t(std::min<uint64_t>(uint64_t(uni(rng) * double(healpix::pixelCount(order))),
                                             healpix::pixelCount(order) - 1));
      it.dx = uni(rng);
      it.dy = uni(rng);
      if (i % 2 == 0) {
        glm::vec3 d(uni(rng) * 2 - 1, uni(rng) * 2 - 1, uni(rng) * 2 - 1);
        it.dir = glm::length(d) > 1e-3f ? glm::normalize(d) : glm::vec3(0, 0, 1);
      } else {
        it.dir = glm::vec3(healpix::pixToVec(order, it.pixel, i % 4 == 1 ? 0.0 : it.dx, i % 4 == 3 ? 0.0 : it.dy));
      }
    }
    vk::Buffer in(ctx, n * sizeof(HealpixItem), vk::MemoryUse::DeviceLocal);
    in.upload(items.data(), n * sizeof(HealpixItem));
    vk::Buffer pixels(ctx, n * 4, vk::MemoryUse::Readback), dirs(ctx, n * 12, vk::MemoryUse::Readback);
    pipeline.setBuffer(0, in);
    pipeline.setBuffer(1, pixels);
    pipeline.setBuffer(2, dirs);
    const uint32_t push[2] = {uint32_t(order), n};
    ctx.submitAndWait([&](VkCommandBuffer cmd) {
      pipeline.dispatch(cmd, push, n / 64, 1);
      VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER, nullptr, VK_ACCESS_SHADER_WRITE_BIT, VK_ACCESS_HOST_READ_BIT};
      ctx.fn.vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &b, 0, nullptr,
                           0, nullptr);
    });
    pixels.invalidate();
    dirs.invalidate();
    const auto* gpuPix = static_cast<const uint32_t*>(pixels.mapped());
    const auto* gpuDir = static_cast<const glm::vec3*>(dirs.mapped());
    uint32_t wrongRandom = 0, wrongBorder = 0;
    double maxDirError = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
      const uint64_t cpu = healpix::vecToPix(order, glm::dvec3(items[i].dir));
      if (gpuPix[i] != cpu) ++(i % 2 == 0 ? wrongRandom : wrongBorder);
      const glm::dvec3 ref = healpix::pixToVec(order, items[i].pixel, items[i].dx, items[i].dy);
      maxDirError = std::max(maxDirError, glm::length(glm::dvec3(gpuDir[i]) - ref));
    }
    std::printf("[ healpix  ] %s order %2d: direction -> pixel differs for %u of %u random and %u of %u "
                "on-border directions; pixel -> direction max error %.2e\n",
                fp32 ? "fp32" : "fp64", order, wrongRandom, n / 2, wrongBorder, n / 2, maxDirError);
    // fp64: only atan2's and cos/sin's last bits differ from glibc's (the
    // direction then differs by the float vector's rounding). fp32: a border
    // direction lands on either side; random ones almost never near one.
    // fp32: an index error of about 1e-7 Nside pixel widths flips ~2e-6 Nside of random directions.
    EXPECT_LE(wrongRandom, fp32 ? uint32_t(n / 2 * std::max(1e-3, 2e-6 * double(1 << order))) : 0u) << "order " << order;
    if (!fp32) {
      EXPECT_LE(wrongBorder, n / 2 / 10000) << "order " << order;
    }
    EXPECT_LT(maxDirError, fp32 ? 2e-6 : 2e-7) << "order " << order;
  }
}
INSTANTIATE_TEST_SUITE_P(Variants, GpuHealpix, ::testing::Values(false, true),
                         [](const auto& info) { return info.param ? "fp32" : "fp64"; });

// ---------------------------------------------------------------- rendering

// Two-sided p-value of Student's t with nu degrees of freedom:
// I_{nu / (nu + t^2)}(nu / 2, 1 / 2) (continued fraction, Numerical Recipes' betacf).
double studentTwoSidedP(double t, double nu) {
  const double x = nu / (nu + t * t), a = nu / 2, b = 0.5;
  if (x <= 0.0) return 0.0;
  auto cf = [](double a, double b, double x) {
    double c = 1.0, d = 1.0 - (a + b) * x / (a + 1.0);
    d = 1.0 / (std::fabs(d) < 1e-300 ? 1e-300 : d);
    double h = d;
    for (int m = 1; m < 300; ++m) {
      for (int pass = 0; pass < 2; ++pass) {
        const double num = pass == 0 ? m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m))
                                     : -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1));
        d = 1.0 + num * d;
        d = 1.0 / (std::fabs(d) < 1e-300 ? 1e-300 : d);
        c = 1.0 + num / c;
        if (std::fabs(c) < 1e-300) c = 1e-300;
        h *= d * c;
        if (pass == 1 && std::fabs(d * c - 1.0) < 1e-14) return h;
      }
    }
    return h;
  };
  const double front = std::exp(std::lgamma(a + b) - std::lgamma(a) - std::lgamma(b) + a * std::log(x) + b * std::log1p(-x));
  return x < (a + 1) / (a + b + 2) ? front * cf(a, b, x) / a : 1.0 - front * cf(b, a, 1.0 - x) / b;
}

TEST(GpuStatistics, StudentT) {
  EXPECT_NEAR(studentTwoSidedP(2.131, 15), 0.05, 2e-4);
  EXPECT_NEAR(studentTwoSidedP(2.947, 15), 0.01, 1e-4);
  EXPECT_NEAR(studentTwoSidedP(1.96, 1e6), 0.05, 1e-4);
}

struct MethodCase {
  Method method;
  bool fp32;
  SamplerKind sampler = SamplerKind::Stratified;
};

std::string caseName(const MethodCase& c) {
  std::string name = std::string(methodName(c.method)) + (c.fp32 ? "_fp32" : "_fp64") +
                     (c.sampler == SamplerKind::Independent ? "_independent" : "");
  std::replace(name.begin(), name.end(), '-', '_');
  return name;
}

// Not env and mis in fp32: the shader without doubles descends the
// environment's tree with a float point, which picks another pixel than the
// CPU's double point now and then; GpuOtherSeedsFp32 checks them.
const std::vector<MethodCase> kCases = {
    {Method::Uniform, false}, {Method::Cosine, false}, {Method::Env, false}, {Method::Brdf, false},
    {Method::Mis, false},     {Method::Uniform, true}, {Method::Cosine, true}, {Method::Brdf, true},
    {Method::Env, false, SamplerKind::Independent},    {Method::Mis, false, SamplerKind::Independent},
    {Method::MisCompensated, false}};

// Renders on the GPU (validation on) and checks that nothing was reported.
GpuRenderResult renderGpu(const Scene& scene, const RenderSettings& rs, bool fp32) {
  GpuRenderer gpu(gpuOptions(fp32));
  if (!fp32 && !gpu.float64()) throw std::runtime_error("device without shaderFloat64");
  gpu.setScene(scene);
  GpuRenderResult g = gpu.render(rs);
  EXPECT_GE(g.gpuSeconds, 0.0);
  return g;
}

class GpuSameSeed : public ::testing::TestWithParam<MethodCase> {};

// The test scene (sunrise with its sun, spheres down to GGX alpha 0.02) at
// 64 spp, GPU and CPU with the same seed: every pixel identical within
// kRelTolerance but for a fraction kMaxDifferentFraction, left to
// discontinuities (a shadow ray grazing a silhouette, an environment lookup
// at a pixel border) that the last bits of cos, sin and pow can flip.
TEST_P(GpuSameSeed, MatchesCpuImage) {
  constexpr float kRelTolerance = 1e-4f;
  constexpr double kMaxDifferentFraction = 0.005;
  const MethodCase c = GetParam();
  const Scene& scene = testScene();
  RenderSettings rs = settings(c.method, 64, 1);
  rs.options.sampler = c.sampler;
  GpuRenderResult g = renderGpu(scene, rs, c.fp32);
  expectNoValidationMessages();
  RenderResult cpu = renderCpu(scene, rs);

  ASSERT_EQ(g.result.image.pixels.size(), cpu.image.pixels.size());
  EXPECT_EQ(g.result.shadedPixels, cpu.shadedPixels);
  EXPECT_EQ(g.result.counters.directions, cpu.counters.directions);
  const size_t n = cpu.image.pixels.size();
  size_t identical = 0, close = 0;
  for (size_t i = 0; i < n; ++i) {
    const glm::vec3 a = g.result.image.pixels[i], b = cpu.image.pixels[i];
    identical += a == b;
    bool ok = true;
    for (int k = 0; k < 3; ++k) ok = ok && std::fabs(a[k] - b[k]) <= kRelTolerance * std::fabs(b[k]);
    close += ok;
  }
  const double differentFraction = 1.0 - double(close) / double(n);
  const double shadowRayDiff =
      double(int64_t(g.result.counters.shadowRays) - int64_t(cpu.counters.shadowRays)) / double(cpu.counters.shadowRays);
  std::printf("[ same seed] %-7s %s %s: %zu px, bit-identical %.2f %%, within %.0e relative %.2f %% (%zu px differ), "
              "shadow rays %+.1e relative\n",
              methodName(c.method), c.fp32 ? "fp32" : "fp64", c.sampler == SamplerKind::Independent ? "iid" : "strat", n, 100.0 * identical / n, double(kRelTolerance),
              100.0 * close / n, n - close, shadowRayDiff);
  EXPECT_LE(differentFraction, kMaxDifferentFraction);
  EXPECT_LT(std::fabs(shadowRayDiff), 1e-3);
}
INSTANTIATE_TEST_SUITE_P(Baselines, GpuSameSeed, ::testing::ValuesIn(kCases),
                         [](const auto& info) { return caseName(info.param); });

// A scene for statistics: the same spheres with GGX alpha >= 0.3 and a
// smooth sky (dynamic range about 30) instead of the sunrise's sun, so that
// every method's 64-spp estimate is close to normal and a per-pixel test at
// a Sidak-corrected level is meaningful (under sunrise, uniform sampling
// hits the sun in one pixel run out of dozens).
const Scene& statisticsScene() {
  static const Scene scene = [] {
    Scene s = readSceneFile(kData + "/scenes/spheres.json");
    for (size_t i = 0; i < s.materials.size(); ++i)
      if (s.materials[i].type == MaterialType::Ggx) s.materials[i].alpha = std::max(s.materials[i].alpha, 0.3f);
    const int order = 5;
    std::vector<glm::vec3> radiance(healpix::pixelCount(order));
    const glm::dvec3 sun = glm::normalize(glm::dvec3(0.5, 0.5, 1.0));  // HEALPix frame: z is up
    for (uint64_t p = 0; p < radiance.size(); ++p) {
      const glm::dvec3 d = healpix::pixToVec(order, p);
      const double sky = d.z > 0.0 ? 0.5 + 0.5 * d.z : 0.3;
      const double glow = 8.0 * std::exp(20.0 * (glm::dot(d, sun) - 1.0));
      radiance[p] = glm::vec3(float(0.3 * sky + glow), float(0.4 * sky + 0.9 * glow), float(0.6 * sky + 0.7 * glow));
    }
    s.environment = environmentFromPixels(order, std::move(radiance), 25.0f);
    return s;
  }();
  return scene;
}


// The GPU image at `spp` (seed 1, the device's default shader) against
// kCpuRuns CPU renders with seeds 1000 + k: per pixel, Student's t of the
// GPU luminance against the CPU runs' mean and spread, none beyond the
// Sidak-corrected 1 % level; and the relative difference of the image means
// below 4 standard errors and below 2 %. Pixels whose CPU runs all agree
// (the sky) must match to 1e-4.
void expectAgreesWithCpuStatistically(Method method, int kSpp, bool fp32 = false,
                                      const Scene& scene = statisticsScene()) {
  constexpr int kCpuRuns = 32;
  GpuRenderResult g;
  {
    GpuRenderer gpu(gpuOptions(fp32));
    gpu.setScene(scene);
    g = gpu.render(settings(method, kSpp, 1));
  }
  expectNoValidationMessages();
  const size_t n = g.result.image.pixels.size();
  std::vector<double> sum(n, 0.0), sum2(n, 0.0), lo(n, INFINITY), hi(n, -INFINITY);
  for (int run = 0; run < kCpuRuns; ++run) {
    RenderResult r = renderCpu(scene, settings(method, kSpp, 1000 + run));
    for (size_t i = 0; i < n; ++i) {
      const double y = luminance(r.image.pixels[i]);
      sum[i] += y;
      sum2[i] += y * y;
      lo[i] = std::min(lo[i], y);
      hi[i] = std::max(hi[i], y);
    }
  }
  // The CPU with the GPU's seed: a pixel beyond the threshold that it
  // reproduces is the estimator's own tail (32 runs cannot judge a rare
  // large sample), not a difference between the devices. In fp32 the GPU's
  // directions are the CPU's but for float rounding, which moves a tail
  // sample's value: there the CPU with the same seed beyond 3 standard
  // deviations on the same side is the same tail.
  const RenderResult same = renderCpu(scene, settings(method, kSpp, 1));
  const double sidak = 1.0 - std::pow(1.0 - 0.01, 1.0 / double(n));
  double gpuTotal = 0.0, cpuTotal = 0.0, varTotal = 0.0, worstP = 1.0, worstT = 0.0;
  size_t beyond3 = 0, tested = 0, failed = 0, sharedTail = 0;
  for (size_t i = 0; i < n; ++i) {
    const double mean = sum[i] / kCpuRuns;
    const double var = std::max(0.0, (sum2[i] - kCpuRuns * mean * mean) / (kCpuRuns - 1));
    const double y = luminance(g.result.image.pixels[i]);
    gpuTotal += y;
    cpuTotal += mean;
    varTotal += var;
    if (lo[i] == hi[i]) {
      EXPECT_NEAR(y, mean, 1e-4 * std::fabs(mean)) << "pixel " << i;
      continue;
    }
    ++tested;
    const double t = (y - mean) / std::sqrt(var * (1.0 + 1.0 / kCpuRuns));
    const double p = studentTwoSidedP(t, kCpuRuns - 1);
    beyond3 += std::fabs(t) > 3.0;
    if (p < worstP) {
      worstP = p;
      worstT = t;
    }
    if (!(p < sidak)) continue;
    const double ySame = luminance(same.image.pixels[i]);
    const double tSame = (ySame - mean) / std::sqrt(var * (1.0 + 1.0 / kCpuRuns));
    if (std::fabs(y - ySame) <= 1e-4 * std::fabs(ySame) || (fp32 && tSame * t > 0.0 && std::fabs(tSame) > 3.0))
      ++sharedTail;
    else
      ++failed;
  }
  const double relDiff = (gpuTotal - cpuTotal) / cpuTotal;
  const double relSe = std::sqrt(varTotal * (1.0 + 1.0 / kCpuRuns)) / cpuTotal;
  std::printf("[ t-test   ] %-7s: %zu px tested, |t| > 3: %zu (%.2f %%; %.2f %% expected), worst t %+.2f (p %.1e, "
              "Sidak threshold %.1e; %zu beyond it as on the CPU with the same seed), image mean %+.3f %% (standard "
              "error %.3f %%)\n",
              methodName(method), tested, beyond3, 100.0 * beyond3 / std::max<size_t>(tested, 1),
              100.0 * studentTwoSidedP(3.0, kCpuRuns - 1), worstT, worstP, sidak, sharedTail, 100.0 * relDiff,
              100.0 * relSe);
  EXPECT_GT(tested, n / 2);
  EXPECT_EQ(failed, 0u) << "pixels beyond the Sidak-corrected threshold";
  EXPECT_LT(std::fabs(relDiff), std::min(4.0 * relSe, 0.02));
}

class GpuOtherSeeds : public ::testing::TestWithParam<Method> {};
TEST_P(GpuOtherSeeds, AgreesWithCpuStatistically) { expectAgreesWithCpuStatistically(GetParam(), 64); }
// The same at 256 spp, where a pixel's estimate takes several dispatches.
class GpuOtherSeedsSlow : public ::testing::TestWithParam<Method> {};
TEST_P(GpuOtherSeedsSlow, AgreesWithCpuStatistically) { expectAgreesWithCpuStatistically(GetParam(), 256); }
INSTANTIATE_TEST_SUITE_P(Ht, GpuOtherSeeds, ::testing::Values(Method::Ht, Method::HtBiased, Method::HtVis, Method::HtVisBiased),
                         [](const auto& info) {
                           std::string name = methodName(info.param);
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });
// Not wis: at 256 spp its estimate has rare large outliers (seed 1 puts a
// pixel 16 standard deviations from 32 other seeds' mean on the CPU too), so
// a t-test's normal approximation fails; GpuHighSpp shows its GPU values
// equal the CPU's for the same seed.
INSTANTIATE_TEST_SUITE_P(Spp256, GpuOtherSeedsSlow,
                         ::testing::Values(Method::Ht, Method::HtBiased, Method::HtVis, Method::HtVisBiased, Method::Mis,
                                           Method::Ris, Method::Tsis),
                         [](const auto& info) {
                           std::string name = methodName(info.param);
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });
INSTANTIATE_TEST_SUITE_P(Baselines, GpuOtherSeeds,
                         ::testing::Values(Method::Uniform, Method::Cosine, Method::Env, Method::Brdf, Method::Mis),
                         [](const auto& info) { return std::string(methodName(info.param)); });
// The shader without doubles, where it warps points in float.
class GpuOtherSeedsFp32 : public ::testing::TestWithParam<Method> {};
TEST_P(GpuOtherSeedsFp32, AgreesWithCpuStatistically) { expectAgreesWithCpuStatistically(GetParam(), 64, true); }
INSTANTIATE_TEST_SUITE_P(EnvironmentDescent, GpuOtherSeedsFp32, ::testing::Values(Method::Env, Method::Mis, Method::Ris),
                         [](const auto& info) { return std::string(methodName(info.param)); });
// HT in fp32 compares its thresholds in float: other samples than the CPU's,
// the same estimator (slow tier).
class GpuOtherSeedsFp32Slow : public ::testing::TestWithParam<Method> {};
TEST_P(GpuOtherSeedsFp32Slow, AgreesWithCpuStatistically) { expectAgreesWithCpuStatistically(GetParam(), 64, true); }
INSTANTIATE_TEST_SUITE_P(HtThresholds, GpuOtherSeedsFp32Slow,
                         ::testing::Values(Method::Ht, Method::HtVis, Method::HtVisBiased),
                         [](const auto& info) {
                           std::string name = methodName(info.param);
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

// restir in float: other rounding of W and the weights, the same estimator (slow tier).
INSTANTIATE_TEST_SUITE_P(Reuse, GpuOtherSeedsFp32Slow, ::testing::Values(Method::Restir, Method::RestirBiased),
                         [](const auto& info) {
                           std::string name = methodName(info.param);
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

// ---------------------------------------------------------------- restir

// The whole image is one tile whatever the tile limit, and chains run in
// groups of at most the batch limit: with groups of 3 chains, on an image
// whose sides are no multiple of the workgroup, every pixel's count and
// value are the CPU's for the same seed.
TEST(GpuRestir, GroupsOfChainsMatchTheCpu) {
  GpuOptions o = gpuOptions();
  o.maxTileSide = 16;
  o.batchLimit = 3;
  GpuRenderer gpu(o);
  if (!gpu.float64()) GTEST_SKIP() << "device without shaderFloat64";
  gpu.setScene(testScene());
  for (Method m : {Method::Restir, Method::RestirBiased}) {
    RenderSettings rs = settings(m, 10, 5, 37, 21);
    rs.options.restirRadius = 5;
    rs.pixelCounts = true;
    const GpuRenderResult g = gpu.render(rs);
    const RenderResult cpu = renderCpu(testScene(), rs);
    EXPECT_EQ(g.tiles, 1);
    EXPECT_EQ(g.result.counters.directions, cpu.counters.directions);
    EXPECT_EQ(g.result.counters.shadowRays, cpu.counters.shadowRays);
    EXPECT_EQ(g.result.pixelDirections, cpu.pixelDirections);
    double worst = 0.0;
    for (size_t i = 0; i < cpu.image.pixels.size(); ++i)
      for (int k = 0; k < 3; ++k) {
        const double a = g.result.image.pixels[i][k], b = cpu.image.pixels[i][k];
        worst = std::max(worst, std::fabs(a - b) / (std::fabs(b) + 1e-9));
      }
    std::printf("[ restir   ] %s: largest relative difference %.1e\n", methodName(m), worst);
    // The reuse weights are ratios of BRDF values at several points, whose
    // pow and sqrt differ in their last bits between the devices.
    EXPECT_LT(worst, 1e-3) << methodName(m);
  }
  expectNoValidationMessages();
}

// ---------------------------------------------------------------- HT

// The CPU's accepted samples at pixel (x, y), drawn as renderCpu and
// estimateDirect draw them; empty where the camera ray escapes.
std::vector<HtSample> cpuHtSamples(const Scene& scene, const RenderSettings& s, const MethodTables& tables, int x,
                                   int y) {
  Ray ray = cameraRay(scene.camera, s.width, s.height, x + 0.5f, y + 0.5f);
  Hit hit;
  if (!intersectScene(scene, ray, 0.0f, INFINITY, hit)) return {};
  ShadingPoint sp{hit.position, hit.normal, -ray.dir, &scene.materials[hit.material]};
  Rng rng(s.seed, pixelStream(x, y, s.width));
  PixelSampler sampler(s.options.sampler, rng.nextUint());
  const HtOptions o = htOptionsFor(s.method, s.options);
  const uint32_t pixelSeed = rng.nextUint();
  HtPoint point(scene, sp, o, tables);
  point.setBudget(double(s.spp));
  const float u = rng.next();
  std::vector<HtSample> out;
  HtCounters counters;
  point.traverse(pixelSeed, u, sampler, out, counters);
  return out;
}

struct HtCase {
  Method method;
  MethodOptions::BrdfBounds bounds;
  bool sphereSequence;
};

// The GPU accepts the CPU's samples: same candidates, cells and acceptance
// values, directions within 1e-5, in the same order, for every pixel of a
// small image. A pixel may differ where a bound computed through pow, cos,
// asin, acos or atan2 (an ulp or so apart on the two sides) lands on the
// acceptance threshold, or a visibility cap or table cell test on its border:
// at most 2 % of the pixels (what differs is printed).
TEST(GpuHt, AcceptsTheCpuSamples) {
  const Scene& scene = testScene();
  GpuOptions o = gpuOptions();
  o.recordHtSamples = true;
  GpuRenderer gpu(o);
  if (!gpu.float64()) GTEST_SKIP() << "device without shaderFloat64: thresholds in float";
  gpu.setScene(scene);
  const HtCase cases[] = {
      {Method::Ht, MethodOptions::BrdfBounds::Analytic, true},
      {Method::HtVis, MethodOptions::BrdfBounds::Analytic, true},
      {Method::HtBiased, MethodOptions::BrdfBounds::Analytic, true},
      {Method::HtVisBiased, MethodOptions::BrdfBounds::Analytic, true},
      {Method::Ht, MethodOptions::BrdfBounds::Table, true},
      {Method::HtVisBiased, MethodOptions::BrdfBounds::Table, true},
      {Method::HtVis, MethodOptions::BrdfBounds::Analytic, false},
  };
  for (const HtCase& c : cases) {
    RenderSettings s = settings(c.method, 16, 7, 40, 24);
    s.options.brdfBounds = c.bounds;
    s.options.htSphereSequence = c.sphereSequence;
    const MethodTables tables = prepareTables(scene, s.method, s.options);
    GpuRenderResult g = gpu.render(s, tables);
    ASSERT_EQ(g.htSamples.size(), size_t(s.width) * s.height);
    size_t pixels = 0, differ = 0, samples = 0, averaged = 0;
    double worstAngle = 0.0;
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x) {
        const std::vector<HtSample> cpu = cpuHtSamples(scene, s, tables, x, y);
        const std::vector<HtSampleRecord>& gpuSamples = g.htSamples[size_t(y) * s.width + x];
        ++pixels;
        samples += cpu.size();
        for (const HtSample& a : cpu) averaged += a.averaged;
        const size_t n = std::min<size_t>(cpu.size(), HT_SAMPLE_LOG_SLOTS);
        bool same = gpuSamples.size() == n;
        for (size_t k = 0; same && k < n; ++k) {
          const HtSample& a = cpu[k];
          const HtSampleRecord& b = gpuSamples[k];
          const double d = glm::length(glm::dvec3(a.dir) - glm::dvec3(b.dir));
          if (a.candidate == b.candidate) worstAngle = std::max(worstAngle, d);
          // h and the weight go through pow (Phong) or the tables: equal within float rounding.
          same = a.candidate == b.candidate && a.level == b.level && std::fabs(a.h - b.h) <= 1e-5f * a.h &&
                 std::fabs(a.weight - b.weight) <= 1e-5f * a.weight && d < 1e-5;
        }
        differ += !same;
      }
    const double fraction = double(differ) / double(pixels);
    std::printf("[ ht       ] %-13s %-8s %-6s: %zu samples (%zu averaged), %zu of %zu pixels differ (%.2f %%), "
                "largest direction difference %.1e\n",
                methodName(c.method), c.bounds == MethodOptions::BrdfBounds::Table ? "table" : "analytic",
                c.sphereSequence ? "sphere" : "faces", samples, averaged, differ, pixels, 100.0 * fraction,
                worstAngle);
    EXPECT_GT(samples, pixels * 4);
    EXPECT_LE(fraction, 0.02) << methodName(c.method);
  }
  expectNoValidationMessages();
}

TEST(GpuRenderTiles, TilesAndOddSizesGiveTheSameImage) {
  const Scene& scene = testScene();
  GpuOptions small = gpuOptions();
  small.maxTileSide = 16;
  const RenderSettings rs = settings(Method::Mis, 4, 3, 61, 29);
  ImageRGB tiled, whole;
  int tiles = 0;
  {
    GpuRenderer r(small);
    r.setScene(scene);
    GpuRenderResult g = r.render(rs);
    tiles = g.tiles;
    tiled = g.result.image;
  }
  {
    GpuRenderer r(gpuOptions());
    r.setScene(scene);
    whole = r.render(rs).result.image;
  }
  EXPECT_EQ(tiles, 4 * 2);
  size_t differ = 0;
  for (size_t i = 0; i < whole.pixels.size(); ++i) differ += tiled.pixels[i] != whole.pixels[i];
  EXPECT_EQ(differ, 0u);
  expectNoValidationMessages();
}

TEST(GpuRenderTiles, BlackEnvironmentAndRefusedMethods) {
  Scene scene = testScene();
  scene.environment = constantEnvironment(2, glm::vec3(0.0f));
  GpuRenderer r(gpuOptions());
  r.setScene(scene);
  // Every method of the registry: black where the GPU path has it, refused where not.
  for (const MethodSpec& info : allMethods()) {
    const Method m = info.method;
    EXPECT_EQ(gpuSupportsMethod(m), info.gpu != nullptr) << info.name;
    if (!info.gpu) {
      EXPECT_THROW(r.render(settings(m, 2, 1, 16, 8)), Error) << info.name;
      continue;
    }
    GpuRenderResult g = r.render(settings(m, 2, 1, 16, 8));
    for (const glm::vec3& p : g.result.image.pixels) ASSERT_EQ(p, glm::vec3(0.0f)) << info.name;
  }
  EXPECT_FALSE(gpuSupportsMethod(Method::Oracle));
  expectNoValidationMessages();
}

// ---------------------------------------------------------------- ris, tsis

// The same-seed and statistical checks above for the competitors: ris in
// both shader variants, tsis and wis in the fp64 one only (they sum in
// doubles). All draw the CPU's random numbers, so the same seed gives the
// same image but for the few pixels where cos, sin or pow flip a decision.
// wis and wis-biased are checked seed for seed only: at the test order their
// f / p has so heavy a tail that 32 CPU runs cannot judge one render (seed 1
// gives t = +26.7 in one pixel, on the CPU as on the GPU, within 1.1e-4).
INSTANTIATE_TEST_SUITE_P(Competitors, GpuSameSeed,
                         ::testing::Values(MethodCase{Method::Ris, false}, MethodCase{Method::Tsis, false}, MethodCase{Method::Wis, false},
                                           MethodCase{Method::WisBiased, false},
                                           MethodCase{Method::Ris, false, SamplerKind::Independent},
                                           MethodCase{Method::Tsis, false, SamplerKind::Independent}),
                         [](const auto& info) {
                           std::string name = caseName(info.param);
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });
INSTANTIATE_TEST_SUITE_P(Competitors, GpuOtherSeeds, ::testing::Values(Method::Ris, Method::Tsis),
                         [](const auto& info) { return std::string(methodName(info.param)); });

// `rs` on the test scene in fp64, in tiles of at most 16 pixels (`a`, with
// `batchLimit` samples per dispatch where not 0) and in one tile (`b`);
// false on a device without shaderFloat64.
bool renderTiledAndWhole(const RenderSettings& rs, GpuRenderResult& a, GpuRenderResult& b,
                         uint32_t batchLimit = 0) {
  const Scene& scene = testScene();
  GpuOptions small = gpuOptions();
  small.maxTileSide = 16;
  small.batchLimit = batchLimit;
  GpuRenderer tiled(small), whole(gpuOptions());
  if (!whole.float64()) return false;
  tiled.setScene(scene);
  whole.setScene(scene);
  a = tiled.render(rs);
  b = whole.render(rs);
  return true;
}

size_t differingPixels(const GpuRenderResult& a, const GpuRenderResult& b) {
  size_t differ = 0;
  for (size_t i = 0; i < a.result.image.pixels.size(); ++i) differ += a.result.image.pixels[i] != b.result.image.pixels[i];
  return differ;
}

// The large arrays read through texel views or through device addresses
// (maps too large for the views): the same images and counts.
// The test scene, and the sphere field for the spheres' BVH and the caps'
// selection through it.
TEST(GpuRenderTilesSlow, TexelViewsAndDeviceAddressesGiveTheSameImage) {
  GpuOptions addresses = gpuOptions();
  addresses.texelViews = false;
  GpuRenderer a(gpuOptions()), b(addresses);
  Scene field = readSceneFile(kData + "/scenes/stress/sphere-field.json");
  field.environmentDesc.nside = 32;
  loadEnvironment(field);
  ASSERT_FALSE(field.sphereBvh.nodes.empty());
  for (const Scene* scene : {&testScene(), static_cast<const Scene*>(&field)}) {
    a.setScene(*scene);
    b.setScene(*scene);
    for (Method m : {Method::Mis, Method::HtVis, Method::HtBiased, Method::HtFrontier, Method::Ris, Method::HtCut}) {
      SCOPED_TRACE(methodName(m));
      const RenderSettings rs = settings(m, 8, 7, 40, 20);
      const GpuRenderResult ga = a.render(rs), gb = b.render(rs);
      EXPECT_TRUE(a.texelViews());
      EXPECT_FALSE(b.texelViews());
      EXPECT_GT(ga.result.shadedPixels, 0u);
      EXPECT_EQ(ga.result.counters.directions, gb.result.counters.directions);
      EXPECT_EQ(ga.result.counters.htNodes, gb.result.counters.htNodes);
      EXPECT_EQ(differingPixels(ga, gb), 0u);
    }
  }
  expectNoValidationMessages();
}

// tsis and wis keep each pixel's partition or product tree in a scratch
// buffer indexed by the pixel's place in its tile (the same index for
// both): small tiles must give the same image.
TEST(GpuCompetitors, TilesGiveTheSameImage) {
  GpuRenderResult a, b;
  if (!renderTiledAndWhole(settings(Method::Tsis, 4, 3, 61, 29), a, b)) GTEST_SKIP() << "device without shaderFloat64";
  EXPECT_EQ(a.tiles, 4 * 2);
  EXPECT_EQ(differingPixels(a, b), 0u);
  expectNoValidationMessages();
}

TEST(GpuCompetitors, TsisAndWisNeedFloat64) {
  for (Method m : {Method::Ris, Method::Tsis, Method::Wis, Method::WisBiased}) EXPECT_TRUE(gpuSupportsMethod(m));
  GpuRenderer r(gpuOptions(true));
  r.setScene(testScene());
  std::vector<Method> float64Methods;
  for (const MethodSpec& info : allMethods())
    if (info.gpu && info.gpu->float64) float64Methods.push_back(info.method);
  EXPECT_EQ(float64Methods, (std::vector<Method>{Method::Wis, Method::WisBiased, Method::Tsis}));
  for (Method m : float64Methods) {
    try {
      r.render(settings(m, 2, 1, 16, 8));
      ADD_FAILURE() << methodName(m) << ": no error";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("shaderFloat64"), std::string::npos) << e.what();
    }
  }
  expectNoValidationMessages();
}


// Faults end in one-line errors, never in a hang: a buffer larger than any
// heap, and a submission that cannot finish (it waits for an event the host
// sets only after the timeout).
TEST(GpuFaults, OutOfMemoryAndTimeoutAreErrors) {
  vk::ContextOptions co;
  co.validation = true;
  co.validationLog = validationLog();
  co.submitTimeoutSeconds = 0.5;
  vk::Context ctx(co);
  VkDeviceSize largest = 0;
  for (uint32_t h = 0; h < ctx.memory.memoryHeapCount; ++h) largest = std::max(largest, ctx.memory.memoryHeaps[h].size);
  try {
    vk::Buffer huge(ctx, 2 * largest, vk::MemoryUse::DeviceLocal);
    ADD_FAILURE() << "a buffer twice the largest heap was created";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("out of GPU memory"), std::string::npos) << e.what();
  }

  VkEventCreateInfo ei{VK_STRUCTURE_TYPE_EVENT_CREATE_INFO};
  VkEvent event = VK_NULL_HANDLE;
  ASSERT_EQ(ctx.fn.vkCreateEvent(ctx.device, &ei, nullptr, &event), VK_SUCCESS);
  try {
    ctx.submitAndWait([&](VkCommandBuffer cmd) {
      ctx.fn.vkCmdWaitEvents(cmd, 1, &event, VK_PIPELINE_STAGE_HOST_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, nullptr, 0,
                      nullptr, 0, nullptr);
    });
    ADD_FAILURE() << "a submission that cannot finish returned";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("did not finish within 0.5 s"), std::string::npos) << e.what();
  }
  ctx.fn.vkSetEvent(ctx.device, event);
  ctx.fn.vkDeviceWaitIdle(ctx.device);
  ctx.fn.vkDestroyEvent(ctx.device, event, nullptr);
}

}  // namespace
}  // namespace ht

// ---------------------------------------------------------------- high spp

namespace ht {
namespace {

struct HighSppCase {
  Method method;
  MethodOptions::BrdfBounds bounds;
  int spp;
};

std::string highSppName(const HighSppCase& c) {
  std::string name = std::string(methodName(c.method)) +
                     (c.bounds == MethodOptions::BrdfBounds::Table ? "_table" : "") + "_" + std::to_string(c.spp);
  std::replace(name.begin(), name.end(), '-', '_');
  return name;
}

std::vector<HighSppCase> highSppCases(int spp) {
  std::vector<HighSppCase> cases;
  // Every method the GPU path has, in the registry's order; HT's also with tabulated BRDF bounds.
  for (const MethodSpec& info : allMethods())
    if (info.gpu) cases.push_back({info.method, MethodOptions::BrdfBounds::Analytic, spp});
  for (const MethodSpec& info : allMethods())
    if (info.gpu && info.family == Family::Ht) cases.push_back({info.method, MethodOptions::BrdfBounds::Table, spp});
  return cases;
}

// The same seed at high spp on both devices: every pixel draws as many
// directions as on the CPU, and gets the CPU's value within float rounding.
// Each pixel's estimate runs in several dispatches here (GpuPixelState); a
// batch that llvmpipe cut short used to lose the rest of a pixel's samples.
// Where a threshold lands on a tie between the two sides' cos, asin or pow
// (mostly HT's visibility caps), a pixel may draw different samples: at
// most two pixels (2.5 % with visibility caps, whose angles go through
// asin and cos), each within 1 % of spp of the CPU's count (a tie at an
// inner node moves its whole subtree).
void expectSameAsCpuAtHighSpp(const HighSppCase& c, int width, int height) {
  const bool caps = c.method == Method::HtVis || c.method == Method::HtVisBiased;
  const size_t kMaxTies = caps ? std::max<size_t>(2, size_t(width) * height / 40) : 2;
  const Scene& scene = testScene();
  GpuOptions o = gpuOptions();
  GpuRenderer gpu(o);
  if (!gpu.float64()) GTEST_SKIP() << "device without shaderFloat64: thresholds in float";
  gpu.setScene(scene);
  RenderSettings rs = settings(c.method, c.spp, 7, width, height);
  rs.options.brdfBounds = c.bounds;
  rs.pixelCounts = true;
  const GpuRenderResult g = gpu.render(rs);
  const RenderResult cpu = renderCpu(scene, rs);
  expectNoValidationMessages();
  const size_t n = cpu.image.pixels.size();
  ASSERT_EQ(g.result.pixelDirections.size(), n);
  ASSERT_EQ(cpu.pixelDirections.size(), n);
  size_t countDiffers = 0, valueDiffers = 0;
  int64_t worstCount = 0;
  for (size_t i = 0; i < n; ++i) {
    const int64_t d = int64_t(g.result.pixelDirections[i]) - int64_t(cpu.pixelDirections[i]);
    if (d != 0) {
      ++countDiffers;
      worstCount = std::max(worstCount, std::abs(d));
      continue;
    }
    const glm::vec3 a = g.result.image.pixels[i], b = cpu.image.pixels[i];
    bool same = true;
    for (int k = 0; k < 3; ++k) same = same && std::fabs(a[k] - b[k]) <= 1e-4f * std::fabs(b[k]) + 1e-7f;
    valueDiffers += !same;
  }
  std::printf("[ high spp ] %-24s: %zu px, %.2f directions per shaded pixel (cpu %.2f), count differs in %zu px "
              "(by at most %lld), value differs in %zu px, %d restarts, %u per batch\n",
              highSppName(c).c_str(), n, double(g.result.counters.directions) / double(g.result.shadedPixels),
              double(cpu.counters.directions) / double(cpu.shadedPixels), countDiffers, (long long)worstCount,
              valueDiffers, g.restarts, g.batchLimit);
  EXPECT_EQ(g.result.shadedPixels, cpu.shadedPixels);
  EXPECT_GE(cpu.counters.directions, uint64_t(c.spp) * cpu.shadedPixels / 2);
  EXPECT_LE(countDiffers, kMaxTies);
  EXPECT_LE(worstCount, std::max(1, c.spp / 100));
  EXPECT_LE(valueDiffers, kMaxTies);
}

class GpuHighSpp : public ::testing::TestWithParam<HighSppCase> {};
TEST_P(GpuHighSpp, MatchesCpuCountsAndImage) { expectSameAsCpuAtHighSpp(GetParam(), 16, 8); }
INSTANTIATE_TEST_SUITE_P(Spp256, GpuHighSpp, ::testing::ValuesIn(highSppCases(256)),
                         [](const auto& info) { return highSppName(info.param); });

class GpuHighSppSlow : public ::testing::TestWithParam<HighSppCase> {};
TEST_P(GpuHighSppSlow, MatchesCpuCountsAndImage) { expectSameAsCpuAtHighSpp(GetParam(), 24, 16); }
INSTANTIATE_TEST_SUITE_P(Spp1024, GpuHighSppSlow, ::testing::ValuesIn(highSppCases(1024)),
                         [](const auto& info) { return highSppName(info.param); });

// Batches far too large for llvmpipe's loop limit: the cut is seen and the
// tile runs again with smaller batches. (Loops in the functions the
// traversal calls keep counts of their own, which the shader cannot see, so
// this alone does not make the result right: the renderer's first batch
// size keeps every count far from the limit, as GpuHighSpp checks.)
TEST(GpuBatches, LoopsCutShortAreRedone) {
  const Scene& scene = testScene();
  GpuOptions o = gpuOptions();
  o.batchLimit = 1u << 20;
  GpuRenderer gpu(o);
  if (!gpu.float64()) GTEST_SKIP() << "device without shaderFloat64";
  gpu.setScene(scene);
  for (Method method : {Method::Ht}) {
    RenderSettings rs = settings(method, 8192, 3, 16, 8);
    rs.pixelCounts = true;
    const GpuRenderResult g = gpu.render(rs);
    const RenderResult cpu = renderCpu(scene, rs);
    size_t differ = 0;
    for (size_t i = 0; i < cpu.pixelDirections.size(); ++i)
      differ += g.result.pixelDirections[i] != cpu.pixelDirections[i];
    std::printf("[ batches  ] %s on %s: %d restarts, %u per batch at the end, %zu px differ in count\n",
                methodName(method), gpu.device().name.c_str(), g.restarts, g.batchLimit, differ);
    if (gpu.device().name.find("llvmpipe") != std::string::npos) {
      EXPECT_GT(g.restarts, 0);
      EXPECT_LT(g.batchLimit, o.batchLimit);
    }
    EXPECT_GT(g.result.counters.directions, cpu.counters.directions / 2);
  }
  expectNoValidationMessages();
}


// A pixel whose loops the driver cuts in one batch of a submission and not
// in the batches after it still reports the cut (the state keeps it): a
// field of 20000 spheres, whose first batch chooses 16 caps per point
// through the BVH, renders right or ends with the driver's one-line error,
// never with non-finite pixels (llvmpipe: the error).
TEST(GpuBatches, ACutInAnEarlierBatchIsReported) {
  Scene scene = readSceneFile(kData + "/scenes/stress/sphere-field.json");
  const int side = 142;
  scene.spheres.clear();
  for (int i = 0; i < side * side; ++i)
    scene.spheres.push_back({glm::vec3(float(i % side) - 0.5f * float(side - 1), 0.4f, -float(i / side)), 0.4f, 0});
  scene.sphereBvh = buildBvh(scene.spheres);
  scene.camera.lookAt = glm::vec3(0.0f, 0.0f, -0.5f * float(side));
  loadEnvironment(scene);
  GpuRenderer gpu(gpuOptions(true));
  gpu.setScene(scene);
  const RenderSettings rs = settings(Method::HtFrontier, 16, 3, 32, 16);
  try {
    const GpuRenderResult g = gpu.render(rs);
    for (const glm::vec3& p : g.result.image.pixels) EXPECT_TRUE(std::isfinite(p.x + p.y + p.z));
    EXPECT_EQ(gpu.device().name.find("llvmpipe"), std::string::npos) << "llvmpipe cut no loop";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("ended a shader loop early"), std::string::npos) << e.what();
  }
  expectNoValidationMessages();
}

// ---------------------------------------------------------------- ht-frontier

// ht-frontier in the fp64 shader draws the CPU's directions: its tables
// (own ones refined on the GPU, the plane's shared one built on the host)
// split the same nodes in the same order, so the same seed gives the same
// image and the same counts.
INSTANTIATE_TEST_SUITE_P(Product, GpuSameSeed,
                         ::testing::Values(MethodCase{Method::HtFrontier, false},
                                           MethodCase{Method::HtFrontier, false, SamplerKind::Independent},
                                           MethodCase{Method::HtCut, false},
                                           MethodCase{Method::HtCut, false, SamplerKind::Independent}),
                         [](const auto& info) {
                           std::string name = caseName(info.param);
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });
INSTANTIATE_TEST_SUITE_P(Product, GpuOtherSeeds, ::testing::Values(Method::HtFrontier),
                         [](const auto&) { return std::string("ht_frontier"); });
// In float the masses' sums and the directions round otherwise: the same
// estimator, other directions.
INSTANTIATE_TEST_SUITE_P(Product, GpuOtherSeedsFp32, ::testing::Values(Method::HtFrontier),
                         [](const auto&) { return std::string("ht_frontier"); });
// ht-cut: in fp64 GpuSameSeed shows the CPU's samples; in float its prefix
// sums and directions round otherwise, the same estimator (slow tier).
INSTANTIATE_TEST_SUITE_P(Product, GpuOtherSeedsFp32Slow, ::testing::Values(Method::HtCut),
                         [](const auto&) { return std::string("ht_cut"); });

// On a glossy floor a point samples the plane's shared table and its
// specular lobe apart; in float too the estimator is the CPU's.
TEST(GpuFrontier, GlossyFloorAgreesInFloat) {
  Scene scene = statisticsScene();
  Material& floor = scene.materials[size_t(scene.planes.at(0).material)];
  floor.type = MaterialType::Ggx;
  floor.alpha = 0.3f;
  floor.specular = glm::vec3(0.04f);
  floor.diffuse = glm::vec3(0.5f);
  expectAgreesWithCpuStatistically(Method::HtFrontier, 64, true, scene);
}

// The nodes each pixel's table bounds (the stats' HT node count) are the
// CPU's, pixel by pixel in sum, and a pixel's scratch is its own: small
// tiles (13 pixels wide at the image's edge, so a block of the scratch
// partly empty) whose tables outlive a dispatch give the same image.
TEST(GpuFrontier, SameTablesAndTilesGiveTheSameImage) {
  const RenderSettings rs = settings(Method::HtFrontier, 8, 3, 61, 29);
  GpuRenderResult a, b;
  if (!renderTiledAndWhole(rs, a, b, 3)) GTEST_SKIP() << "device without shaderFloat64";
  const RenderResult cpu = renderCpu(testScene(), rs);
  EXPECT_EQ(a.tiles, 4 * 2);
  EXPECT_EQ(a.batchLimit, 3u);
  EXPECT_GT(cpu.counters.htNodes, 0u);
  EXPECT_EQ(b.result.counters.htNodes, cpu.counters.htNodes);
  EXPECT_EQ(a.result.counters.htNodes, cpu.counters.htNodes);
  EXPECT_EQ(b.result.counters.directions, uint64_t(8) * cpu.shadedPixels);
  EXPECT_EQ(differingPixels(a, b), 0u);
  expectNoValidationMessages();
}

// The stress scenes (at Nside 64, so that the maps load quickly), each
// rendered with the same seed on both devices, pixel for pixel.
struct StressComparison {
  std::string scene;
  size_t pixels = 0, countDiffers = 0, valueDiffers = 0;
  double worst = 0.0;  // largest relative difference where the counts agree
  double gpuSum = 0.0, cpuSum = 0.0;  // the images' sums over pixels and channels
  uint64_t gpuNodes = 0, cpuNodes = 0, gpuShaded = 0, cpuShaded = 0;
};

std::vector<StressComparison> compareOnStressScenes(GpuRenderer& gpu, Method method, int spp) {
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(kData + "/scenes/stress"))
    if (e.path().extension() == ".json") files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  EXPECT_GE(files.size(), 8u);
  std::vector<StressComparison> out;
  for (const std::string& file : files) {
    Scene scene = readSceneFile(file);
    scene.environmentDesc.nside = 64;
    loadEnvironment(scene);
    gpu.setScene(scene);
    RenderSettings rs = settings(method, spp, 5, 40, 20);
    rs.pixelCounts = true;
    const GpuRenderResult g = gpu.render(rs);
    const RenderResult cpu = renderCpu(scene, rs);
    StressComparison c;
    c.scene = std::filesystem::path(file).stem().string();
    c.pixels = cpu.image.pixels.size();
    for (size_t i = 0; i < c.pixels; ++i) {
      if (g.result.pixelDirections[i] != cpu.pixelDirections[i]) {
        ++c.countDiffers;
        continue;
      }
      const glm::vec3 a = g.result.image.pixels[i], b = cpu.image.pixels[i];
      bool same = true;
      for (int k = 0; k < 3; ++k) {
        same = same && std::fabs(a[k] - b[k]) <= 1e-4f * std::fabs(b[k]) + 1e-7f;
        c.worst = std::max(c.worst, double(std::fabs(a[k] - b[k]) / (std::fabs(b[k]) + 1e-3f)));
      }
      c.valueDiffers += !same;
      c.gpuSum += double(a.x) + double(a.y) + double(a.z);
      c.cpuSum += double(b.x) + double(b.y) + double(b.z);
    }
    c.gpuNodes = g.result.counters.htNodes;
    c.cpuNodes = cpu.counters.htNodes;
    c.gpuShaded = g.result.shadedPixels;
    c.cpuShaded = cpu.shadedPixels;
    std::printf("[ stress   ] %-14s %-22s: %zu px, count differs in %zu, value in %zu (at most %.1e relative), "
                "nodes %llu (cpu %llu)\n",
                methodName(method), c.scene.c_str(), c.pixels, c.countDiffers, c.valueDiffers, c.worst,
                (unsigned long long)c.gpuNodes, (unsigned long long)c.cpuNodes);
    out.push_back(c);
  }
  expectNoValidationMessages();
  return out;
}

// The agreement the product methods keep on every stress scene: the CPU's
// count of directions at every pixel and its shaded pixels, its value
// within 1e-4 relative but for at most 2 % of the pixels, the images' sums
// within 1e-4.
void expectStressAgreement(const StressComparison& c) {
  EXPECT_EQ(c.countDiffers, 0u) << c.scene;
  EXPECT_EQ(c.gpuShaded, c.cpuShaded) << c.scene;
  EXPECT_LE(c.valueDiffers, c.pixels / 50) << c.scene;
  EXPECT_LT(std::fabs(c.gpuSum - c.cpuSum), 1e-4 * c.cpuSum) << c.scene;
}

// ht-frontier: every pixel draws the CPU's count of directions, and the
// table nodes agree in sum; the CPU's value within 1e-4 relative but for at
// most 2 % of the pixels, where an ulp of a direction (the shader's float
// cos and sin) moves it in a lobe (mirror-ggx's alpha 0.01 turns that into
// 5e-4) and, rarely, by more (one pixel of grazing-view by 5 %); the
// images' sums within 1e-4.
TEST(GpuFrontierSlow, StressScenesMatchTheCpu) {
  GpuRenderer gpu(gpuOptions());
  if (!gpu.float64()) GTEST_SKIP() << "device without shaderFloat64";
  for (const StressComparison& c : compareOnStressScenes(gpu, Method::HtFrontier, 16)) {
    expectStressAgreement(c);
    EXPECT_EQ(c.gpuNodes, c.cpuNodes) << c.scene;
  }
}

// ---------------------------------------------------------------- ht-cut

// ht-cut on every stress scene: every pixel draws the CPU's count, and the
// values agree as ht-frontier's do.
TEST(GpuCut, StressScenesMatchTheCpu) {
  GpuRenderer gpu(gpuOptions());
  if (!gpu.float64()) GTEST_SKIP() << "device without shaderFloat64";
  for (const StressComparison& c : compareOnStressScenes(gpu, Method::HtCut, 16)) expectStressAgreement(c);
}

// Every batch weighs the cut again at its pixel's point: batches of three
// directions and tiles 13 pixels wide at the image's edge give the image of
// one batch and one tile, and the CPU's counts.
TEST(GpuCut, BatchesAndTilesGiveTheSameImage) {
  const RenderSettings rs = settings(Method::HtCut, 8, 3, 61, 29);
  GpuRenderResult a, b;
  if (!renderTiledAndWhole(rs, a, b, 3)) GTEST_SKIP() << "device without shaderFloat64";
  const RenderResult cpu = renderCpu(testScene(), rs);
  EXPECT_EQ(a.tiles, 4 * 2);
  EXPECT_EQ(a.batchLimit, 3u);
  EXPECT_EQ(a.result.counters.directions, cpu.counters.directions);
  EXPECT_EQ(b.result.counters.directions, uint64_t(8) * cpu.shadedPixels);
  EXPECT_EQ(differingPixels(a, b), 0u);
  expectNoValidationMessages();
}

// restir and restir-biased on every stress scene: every pixel draws the
// CPU's count, and the values agree as ht-frontier's do.
TEST(GpuRestir, StressScenesMatchTheCpu) {
  GpuRenderer gpu(gpuOptions());
  if (!gpu.float64()) GTEST_SKIP() << "device without shaderFloat64";
  for (Method m : {Method::Restir, Method::RestirBiased})
    for (const StressComparison& c : compareOnStressScenes(gpu, m, 16)) expectStressAgreement(c);
}

// The seed's methods accept the CPU's candidates on every stress scene too
// (the sun's leaves of pixel-sun-1e6 accept far more candidates than the
// pending list holds). Every pixel draws the CPU's count of directions, and
// `ht` visits the CPU's nodes in sum. With visibility caps a threshold can
// land on a tie between the two sides' asin and cos (GpuHighSpp): at most
// 2.5 % of the pixels draw another count, and the node sum is within
// 0.1 %. The values agree within 1e-4 relative but for at most 5 % of the
// pixels: mirror-ggx's lobe (alpha 0.01) turns an ulp of a direction into
// 1e-3, and a tie in a leaf's visible fraction changes its h by a fifth.
TEST(GpuHtSlow, StressScenesMatchTheCpu) {
  GpuRenderer gpu(gpuOptions());
  if (!gpu.float64()) GTEST_SKIP() << "device without shaderFloat64";
  for (Method m : {Method::Ht, Method::HtVis, Method::HtVisBiased}) {
    const bool caps = m != Method::Ht;
    for (const StressComparison& c : compareOnStressScenes(gpu, m, 16)) {
      const std::string what = std::string(methodName(m)) + " " + c.scene;
      EXPECT_LE(c.countDiffers, caps ? c.pixels / 40 : 0) << what;
      EXPECT_LE(c.valueDiffers, c.pixels / 20) << what;
      EXPECT_EQ(c.gpuShaded, c.cpuShaded) << what;
      EXPECT_GT(c.cpuNodes, 0u) << what;
      const uint64_t nodeDiff = c.gpuNodes > c.cpuNodes ? c.gpuNodes - c.cpuNodes : c.cpuNodes - c.gpuNodes;
      EXPECT_LE(nodeDiff, caps ? c.cpuNodes / 1000 : 0) << what;
    }
  }
}

}  // namespace
}  // namespace ht
