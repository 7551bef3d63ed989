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
#include "tsis.h"
#include "ht_frontier.h"
#include "wis.h"
#include "common.h"  // shaders/common.h

namespace ht {

namespace {

bool isHt(Method m) { return methodInfo(m).family == Family::Ht; }
// The methods that read HT's node geometry on the CPU.
bool usesHtGeometry(Method m) {
  const Family f = methodInfo(m).family;
  return f == Family::Ht || f == Family::Oracle || f == Family::Product;
}

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

  uint64_t tables = 0;
  if (usesHtGeometry(in.method)) tables += add("HT node geometry", nodes * 20);
  if ((isHt(in.method) || in.method == Method::HtFrontier) && !in.gpu) tables += add("HT node records", nodes * 32);
  if (in.method == Method::Oracle) {
    const int k = std::clamp(in.options.oracleOrder, 0, in.envOrder);
    tables += add("oracle tables (per thread)", uint64_t(std::max(in.threads, 1)) * MaxAvgTree::levelSize(k) * 40);
  }
  if (in.method == Method::Wis || in.method == Method::WisBiased) {
    const int k = std::clamp(in.options.wisOrder, 0, std::min(in.envOrder, WisPoint::kMaxOrder));
    tables += add("wis node centres", MaxAvgTree::levelOffset(k + 1) * 12);
  }
  if (in.method == Method::HtFrontier) {
    tables += add("ht-frontier shared tables (per thread, at most)",
                  uint64_t(std::max(in.threads, 1)) * kFrontierSharedTables * kFrontierSharedTableBytes);
    tables += add("ht-frontier colour bins, chroma and centroids (and their sums while built)", nodes * 25);
  }
  uint64_t compensated = 0;
  if (in.method == Method::MisCompensated)
    compensated = tables += add("mis-compensated tree", nodes * 8);
  uint64_t sat = 0;
  if (in.method == Method::Tsis) {
    const uint64_t n = (uint64_t(1) << std::min(in.envOrder, TsisTable::kMaxLevel)) + 1;
    sat = tables += add("tsis summed-area table", 12 * n * n * 8);
  }
  // The image, and while writing its PNG the 8-bit copy and the encoded file.
  const uint64_t out = add("image and its encodings", image * (12 + 6));

  uint64_t gpu = 0;
  if (in.gpu) {
    // The driver with its shader compiler (LLVM in lavapipe), as measured.
    gpu += kVulkanBytes;
    gpu += radiance + trees + sat + compensated / 2;  // the compensated tree's averages
    if (isHt(in.method)) {
      // Geometry; per pixel of a tile its pending samples and recorded leaves.
      const uint64_t tile =
          uint64_t(std::min(in.width, HT_MAX_TILE_SIDE)) * uint64_t(std::min(in.height, HT_MAX_TILE_SIDE));
      gpu += nodes * 20 + tile * HT_QUEUE_BYTES;
    }
    // ht-frontier: geometry, colour bins, chroma and centroids; a tile's tables (at most GpuRenderer's
    // kCpuScratchBytes on a CPU device, whose buffers are host memory; a GPU's larger scratch is its own).
    if (in.method == Method::HtFrontier) gpu += nodes * 27 + (uint64_t(96) << 20);
    gpu += image * 12;  // the readback of the tiles, gathered
    add("GPU buffers", gpu);
  }
  // The decoder's buffers are freed before the HEALPix map is made.
  e.loadPeak = base + input + std::max(decode, radiance + luminance + resample + trees);
  e.renderPeak = base + radiance + trees + tables + out + gpu;
  return e;
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
