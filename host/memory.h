// What a render will need in memory, estimated before anything large is
// allocated, and the limit it is held to (system_memory.h: what the machine has).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "method.h"

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

// Throws ht::Error naming the need, its largest parts and the limit when
// the estimate's peak exceeds `limit`.
void checkMemory(const MemoryEstimate& e, uint64_t limit, const std::string& limitSource);

}  // namespace ht
