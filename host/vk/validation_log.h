// Messages of the Khronos validation layer, counted. Shared (std::shared_ptr)
// so that a test can still read what was reported while the device and the
// instance were being destroyed.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ht::vk {

struct ValidationLog {
  uint64_t errors = 0;
  uint64_t warnings = 0;
  bool print = true;                  // also print each message on stderr
  std::vector<std::string> messages;  // the first few
};

}  // namespace ht::vk
