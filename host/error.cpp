#include "error.h"

#include <fmt/format.h>

namespace ht {

std::string oneLine(const std::string& s) {
  std::string r;
  r.reserve(s.size());
  for (char c : s) {
    if (c == '\n') {
      r += "\\n";
    } else if (c == '\r') {
      r += "\\r";
    } else if ((unsigned char)c < 0x20 || c == 0x7f) {
      r += fmt::format("\\x{:02x}", (unsigned)(unsigned char)c);
    } else {
      r += c;
    }
  }
  return r;
}

}  // namespace ht
