// What the machine and the process have in memory: the available memory,
// the peak resident set, huge-page advice, byte sizes in and out of text.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace ht {

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

}  // namespace ht
