#include "memory.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <string>

#include <fmt/format.h>

#include "environment.h"
#include "error.h"
#include "system_memory.h"
#include "tree.h"

namespace ht {

namespace {

// Code, libraries and TBB, as measured (peak RSS) rendering a tiny scene.
constexpr uint64_t kBaseBytes = uint64_t(12) << 20;
constexpr uint64_t kVulkanBytes = uint64_t(224) << 20;

}  // namespace

MemoryEstimate estimateRenderMemory(const MemoryInputs& in) {
  MemoryEstimate e;
  const uint64_t pixels = MaxAvgTree::levelSize(in.envOrder);  // 12 Nside^2
  const uint64_t nodes = MaxAvgTree::levelOffset(in.envOrder + 1);
  const uint64_t image = uint64_t(in.width) * uint64_t(in.height);
  auto add = [&](const std::string& what, uint64_t bytes) {
    if (bytes > 0) e.parts.emplace_back(what, bytes);
    return bytes;
  };
  const uint64_t base = add("program", kBaseBytes);
  const uint64_t input = add("input map", uint64_t(in.inputWidth) * uint64_t(in.inputHeight) * 12);
  const uint64_t decode = add("decoding the input map (while read)", in.inputDecodeBytes);
  const uint64_t radiance = add("HEALPix radiance", pixels * 12);
  const uint64_t luminance = add("luminance (while building the trees)", pixels * 4);
  // Each thread resamples a group of rings (energy and index per pixel, 32
  // bytes) from two running sums over a texel row.
  const uint64_t groupPixels = uint64_t(resampleRingsPerGroup(in.envOrder)) * 4 * (uint64_t(1) << in.envOrder);
  const uint64_t resample = add("ring groups (per thread, while resampling)",
                                uint64_t(std::max(in.threads, 1)) *
                                    (groupPixels * 32 + (uint64_t(in.inputWidth) + 1) * 48));
  const uint64_t trees = add("max/avg trees", nodes * 8);

  // The method's tables, and its part of the GPU's buffers.
  MethodMemory method;
  if (const auto memory = methodSpec(in.method).memory) memory(in, method);
  uint64_t tables = 0;
  for (const auto& [what, bytes] : method.tables) tables += add(what, bytes);
  // The image, and while writing its PNG the 8-bit copy and the encoded file.
  const uint64_t out = add("image and its encodings", image * (12 + 6));

  uint64_t gpu = 0;
  if (in.gpu) {
    // The driver with its shader compiler (LLVM in lavapipe), as measured.
    gpu += kVulkanBytes;
    gpu += radiance + trees + method.gpu;
    gpu += image * 12;  // the readback of the tiles, gathered
    add("GPU buffers", gpu);
  }
  // The decoder's buffers are freed before the HEALPix map is made.
  e.loadPeak = base + input + std::max(decode, radiance + luminance + resample + trees);
  e.renderPeak = base + radiance + trees + tables + out + gpu;
  return e;
}

void MethodMemory::table(const char* what, uint64_t bytes) {
  if (bytes > 0) tables.emplace_back(what, bytes);
}

void checkMemory(const MemoryEstimate& e, uint64_t limit, const std::string& limitSource) {
  if (e.peak() <= limit) return;
  std::vector<std::pair<std::string, uint64_t>> parts = e.parts;
  std::sort(parts.begin(), parts.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
  std::string largest;
  for (size_t i = 0; i < std::min<size_t>(3, parts.size()); ++i)
    largest += fmt::format("{}{} {}", i ? ", " : "", parts[i].first, formatBytes(parts[i].second));
  throw Error(fmt::format("not enough memory: this render needs about {} ({}), more than the limit of {} ({})",
                          formatBytes(e.peak()), largest, formatBytes(limit), limitSource));
}

}  // namespace ht
