// What a render will need in memory, estimated before anything large is
// allocated, and the limit it is held to.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "integrator.h"

namespace ht {

struct MemoryInputs {
  int envOrder = 8;                   // Nside = 2^envOrder
  int inputWidth = 0, inputHeight = 0;  // the equirectangular map read from disk
  uint64_t inputDecodeBytes = 0;        // held while reading it, beyond its pixels
  Method method = Method::Mis;
  MethodOptions options;
  int width = 0, height = 0;  // the image
  int threads = 1;            // CPU threads (per-thread tables)
  bool gpu = false;           // buffers of the Vulkan path (counted as host memory: lavapipe's are)
};

struct MemoryEstimate {
  std::vector<std::pair<std::string, uint64_t>> parts;  // what, bytes
  uint64_t loadPeak = 0;    // reading the map and building the HEALPix environment
  uint64_t renderPeak = 0;  // rendering and writing the outputs
  uint64_t peak() const { return std::max(loadPeak, renderPeak); }
};

MemoryEstimate estimateRenderMemory(const MemoryInputs& in);

// "123", "512K", "1.5G", "2GiB" (binary units). Throws ht::Error.
uint64_t parseByteSize(const std::string& text);
// 80% of what the machine (or the cgroup) has available now.
uint64_t defaultMemoryLimit();
// Asks the kernel to back a large buffer with huge pages where it can:
// first touching hundreds of MiB 4 KiB page by page costs about as much as
// decoding a large map. Only advice; a no-op for buffers under 32 MiB or
// where unsupported.
void adviseHugePages(const void* data, size_t bytes);
// The process's peak resident set so far.
uint64_t peakRssBytes();
std::string formatBytes(uint64_t bytes);

// Throws ht::Error naming the need, its largest parts and the limit when
// the estimate's peak exceeds `limit`.
void checkMemory(const MemoryEstimate& e, uint64_t limit, const std::string& limitSource);

}  // namespace ht
