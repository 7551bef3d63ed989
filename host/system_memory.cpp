#include "system_memory.h"

#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cctype>
#include <cmath>
#include <fstream>
#include <string>

#include <fmt/format.h>

#include "error.h"

namespace ht {

uint64_t parseByteSize(const std::string& text) {
  auto bad = [&] {
    return Error(oneLine(fmt::format("--max-memory: \"{}\" is not a size (bytes, or a number with K, M, G or T)",
                                     text)));
  };
  size_t used = 0;
  double value = 0.0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    throw bad();
  }
  if (!std::isfinite(value) || value <= 0.0 || !std::isdigit((unsigned char)text[0])) throw bad();
  std::string unit = text.substr(used);
  for (char& c : unit) c = char(std::toupper((unsigned char)c));
  if (unit.size() > 1 && unit.back() == 'B') unit.pop_back();
  if (unit.size() > 1 && unit.back() == 'I') unit.pop_back();
  int shift = 0;
  if (unit == "" || unit == "B") shift = 0;
  else if (unit == "K") shift = 10;
  else if (unit == "M") shift = 20;
  else if (unit == "G") shift = 30;
  else if (unit == "T") shift = 40;
  else throw bad();
  const double bytes = std::ldexp(value, shift);
  if (bytes >= 0x1p63) throw bad();
  return uint64_t(bytes);
}

uint64_t defaultMemoryLimit() {
  uint64_t available = 0;
  std::ifstream meminfo("/proc/meminfo");
  for (std::string key; meminfo >> key;) {
    uint64_t kb = 0;
    meminfo >> kb;
    meminfo.ignore(64, '\n');
    if (key == "MemAvailable:") available = kb << 10;
  }
  if (available == 0) {
    const long pages = sysconf(_SC_AVPHYS_PAGES), size = sysconf(_SC_PAGESIZE);
    if (pages > 0 && size > 0) available = uint64_t(pages) * uint64_t(size);
  }
  // A container's own limit (cgroup v2) may be tighter than the machine's.
  std::ifstream maxFile("/sys/fs/cgroup/memory.max"), currentFile("/sys/fs/cgroup/memory.current");
  std::string max;
  uint64_t current = 0;
  if (maxFile >> max && max != "max" && currentFile >> current) {
    const uint64_t limit = std::stoull(max);
    const uint64_t left = limit > current ? limit - current : 0;
    available = available == 0 ? left : std::min(available, left);
  }
  if (available == 0) return UINT64_MAX;  // nothing to go by: no limit
  return available / 5 * 4;
}

void adviseHugePages(const void* data, size_t bytes) {
#ifdef MADV_HUGEPAGE
  if (bytes < (size_t(32) << 20)) return;  // smaller blocks may share the heap with others
  const uintptr_t page = uintptr_t(sysconf(_SC_PAGESIZE));
  const uintptr_t begin = (reinterpret_cast<uintptr_t>(data) + page - 1) & ~(page - 1);
  const uintptr_t end = (reinterpret_cast<uintptr_t>(data) + bytes) & ~(page - 1);
  if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#else
  (void)data;
  (void)bytes;
#endif
}

uint64_t peakRssBytes() {
  struct rusage ru {};
  getrusage(RUSAGE_SELF, &ru);
  return uint64_t(ru.ru_maxrss) << 10;  // KiB on Linux
}

std::string formatBytes(uint64_t bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double v = double(bytes);
  int u = 0;
  while (v >= 1024.0 && u < 4) {
    v /= 1024.0;
    ++u;
  }
  return u == 0 ? fmt::format("{} B", bytes) : fmt::format("{:.1f} {}", v, units[u]);
}

}  // namespace ht
