// The Vulkan compute path: renders every method but the brute-force oracle
// (the baselines, the HT family, wis, tsis, ris; wis and tsis on devices
// with shaderFloat64) as renderCpu does, with the same random numbers, on
// any Vulkan 1.2 device with shaderInt64 (lavapipe included). The scene is
// uploaded once; images are rendered in tiles so that no dispatch runs for
// long.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "render.h"
#include "scene.h"
#include "vk/validation_log.h"

namespace ht {

// The shader variant: single precision is the production path on every
// device; the HT_FP64 variant (HEALPix lookups and HT thresholds in double)
// reproduces the CPU reference bit for bit and needs shaderFloat64.
enum class GpuPrecision {
  Auto,  // fp32, except for the methods that exist in fp64 only (wis, tsis) where the device has it
  Fp32,
  Fp64,
};

struct GpuOptions {
  int deviceIndex = -1;     // --gpu-index; -1: discrete > integrated > virtual > CPU
  bool validation = false;  // Khronos validation layer, messages counted in validationLog
  std::shared_ptr<vk::ValidationLog> validationLog;  // null: the renderer keeps its own
  GpuPrecision precision = GpuPrecision::Auto;
  std::string shaderDir;    // empty: shaders/ next to the executable
  int maxTileSide = 512;    // tiles are at most this many pixels wide and high (a multiple of 8)
  bool recordHtSamples = false;  // ht*: keep the first 64 accepted samples of every pixel (tests)
  uint32_t batchLimit = 0;  // samples (ht*: traversal steps) per pixel and dispatch to start with; 0: estimated
  bool texelViews = true;   // the large arrays through texel views where they fit (false: device addresses only)
};

// One Vulkan device, as `htrender info` lists it.
struct GpuDeviceInfo {
  uint32_t index = 0;
  std::string name;
  std::string type;  // discrete, integrated, virtual, cpu, other
  std::string driver;
  std::string apiVersion;
  bool usable = false;
  std::string unusableReason;
  bool shaderFloat64 = false;
  bool timestamps = false;
  double timestampPeriodNs = 0.0;
  uint64_t maxStorageBufferRange = 0;
  uint32_t maxPushConstantsSize = 0;
  uint32_t subgroupSize = 0;
  uint64_t deviceLocalBytes = 0;
};

// Throws ht::Error (one line) when there is no loader or no driver.
std::vector<GpuDeviceInfo> listGpuDevices();
// The device the renderer picks by default, or -1.
int defaultGpuDevice(const std::vector<GpuDeviceInfo>& devices);
// True for the methods the shaders implement.
bool gpuSupportsMethod(Method method);
// Why the GPU path cannot render `method` on `scene`; empty where it can.
std::string gpuSceneLimit(Method method, const Scene& scene);
// <directory of the running executable>/shaders.
std::string shaderDirNextToExecutable();

// One accepted sample of an ht* method, as HtSample (host/ht.h) records it.
struct HtSampleRecord {
  glm::vec3 dir;  // world space
  float h;
  uint64_t candidate;
  int level;
  float weight;
};

struct GpuRenderResult {
  RenderResult result;      // image, wall seconds, counters, as renderCpu
  double gpuSeconds = -1.0; // sum of the dispatches' timestamps; < 0 without timestamps
  double readbackSeconds = -1.0;  // sum of the timestamps around the copies of the results to the host
  int tiles = 0;
  int tileWidth = 0, tileHeight = 0;  // the largest tile
  int submissions = 0;     // queue submissions, each waited for (a few batches each)
  int restarts = 0;        // tiles started again with smaller batches (a driver cut a loop short)
  uint32_t batchLimit = 0; // samples (ht*: traversal steps) per pixel and dispatch, at the end
  // With GpuOptions::recordHtSamples: per pixel (y * width + x), its first accepted samples in order.
  std::vector<std::vector<HtSampleRecord>> htSamples;
};

class GpuRenderer {
 public:
  explicit GpuRenderer(const GpuOptions& options = {});
  ~GpuRenderer();
  GpuRenderer(const GpuRenderer&) = delete;
  GpuRenderer& operator=(const GpuRenderer&) = delete;

  // Uploads the scene's environment (radiance, max/avg trees), materials
  // and shapes; once per scene.
  void setScene(const Scene& scene);
  // `tables`: prepareTables of the scene, method and options; uploaded at
  // the first render that reads them, before its time starts (the CPU's
  // render time leaves out building them, the GPU's uploading them).
  GpuRenderResult render(const RenderSettings& settings, const MethodTables& tables);
  // Uploads the tables a render of `settings` reads now (once per tables).
  void uploadTables(const RenderSettings& settings, const MethodTables& tables);
  // The same, preparing the tables for the scene of setScene (which must
  // still exist); their time is not in the result's.
  GpuRenderResult render(const RenderSettings& settings);

  const GpuDeviceInfo& device() const;
  bool float64() const;  // the device has shaderFloat64 (enabled unless the precision is fp32)
  std::string shaderName() const;  // the SPIR-V file of the last render
  bool texelViews() const;         // the last render read the large arrays through texel views
  const vk::ValidationLog& validationLog() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ht
